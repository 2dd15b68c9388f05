"""Package discovery for the Python side of localpbo.

- `sims/` installs under the import name `localpbo_sims` (a bare `sims` would collide with an
  unrelated PyPI package);
- `ros_ws/src/localpbo_ros/localpbo_ros` (the nodes) installs as `localpbo_ros` too, and
  `ros_ws/src/localpbo_examples/localpbo_examples` (the worked example) as `localpbo_examples`.
Everything else is declared in pyproject.toml.
"""

from setuptools import find_packages, setup

packages = find_packages(
    include=["localpbo_core", "localpbo_core.*", "localpbo_msgs_py", "localpbo_msgs_py.*"]
)
packages += ["localpbo_sims"] + [f"localpbo_sims.{name}" for name in find_packages("sims")]
# The ROS nodes live in the colcon workspace (built there for `ros2 run`) and are also
# importable from this install, so `localpbo run` and the tests use the very same code.
ROS_PKG = "ros_ws/src/localpbo_ros/localpbo_ros"
packages += ["localpbo_ros", "localpbo_ros.benchmarks"]
EXAMPLES_PKG = "ros_ws/src/localpbo_examples/localpbo_examples"
packages += ["localpbo_examples"]

setup(
    packages=packages,
    package_dir={
        "localpbo_sims": "sims",
        "localpbo_ros": ROS_PKG,
        "localpbo_examples": EXAMPLES_PKG,
    },
    package_data={
        "localpbo_sims": ["data/ars/*.npz", "data/ars/LICENSE", "data/ars/README.md"],
        "localpbo_ros": ["localhost_only.xml", "web/*.html", "web/*.js", "web/*.css"],
        "localpbo_core.experiments": ["*.yaml"],
    },
)
