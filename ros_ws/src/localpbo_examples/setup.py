"""ament_python package: the worked example's executables land in lib/localpbo_examples/."""

from setuptools import setup

PACKAGE = "localpbo_examples"

setup(
    name=PACKAGE,
    version="0.1.0",
    packages=[PACKAGE],
    data_files=[
        ("share/ament_index/resource_index/packages", [f"resource/{PACKAGE}"]),
        (f"share/{PACKAGE}", ["package.xml", "README.md"]),
        (f"share/{PACKAGE}/config", ["config/pid_space.yaml"]),
    ],
    install_requires=["setuptools"],
    zip_safe=True,
    description="Worked example for localpbo: a PID controller tuned through its parameters.",
    license="MIT",
    # the launcher of localpbo_ros's executables: the stop guard comes before the node's imports
    entry_points={
        "console_scripts": [
            "pid_controller_node = localpbo_ros.entry:pid_controller_node",
        ],
    },
)
