"""Package discovery: the `sims/` folder installs under the import name `localpbo_sims`.

A bare `sims` import name would collide with an unrelated PyPI package, so the folder is
mapped to a unique import name here; everything else is declared in pyproject.toml.
"""

from setuptools import find_packages, setup

packages = find_packages(include=["localpbo_core", "localpbo_core.*", "localpbo_msgs_py", "localpbo_msgs_py.*"])
packages += ["localpbo_sims"] + [f"localpbo_sims.{name}" for name in find_packages("sims")]

setup(
    packages=packages,
    package_dir={"localpbo_sims": "sims"},
    package_data={"localpbo_sims": ["data/ars/*.npz", "data/ars/LICENSE", "data/ars/README.md"]},
)
