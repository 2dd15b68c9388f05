"""ament_python package: executables land in lib/localpbo_ros/ where `ros2 run` looks."""

from setuptools import setup

PACKAGE = "localpbo_ros"

setup(
    name=PACKAGE,
    version="0.1.0",
    packages=[PACKAGE, f"{PACKAGE}.benchmarks"],
    package_data={PACKAGE: ["localhost_only.xml", "web/*.html", "web/*.js", "web/*.css"]},
    data_files=[
        ("share/ament_index/resource_index/packages", [f"resource/{PACKAGE}"]),
        (f"share/{PACKAGE}", ["package.xml"]),
        (f"share/{PACKAGE}/config", [f"{PACKAGE}/localhost_only.xml"]),
    ],
    install_requires=["setuptools"],
    zip_safe=True,
    description="ROS 2 nodes of localpbo: optimizer, MuJoCo simulator, oracle and judge page.",
    license="MIT",
    # each executable is a launcher in entry.py: the stop guard comes before the node's imports
    entry_points={
        "console_scripts": [
            f"optimizer_node = {PACKAGE}.entry:optimizer_node",
            f"sim_node = {PACKAGE}.entry:sim_node",
            f"oracle_node = {PACKAGE}.entry:oracle_node",
            f"recorder_node = {PACKAGE}.entry:recorder_node",
            f"param_bridge_node = {PACKAGE}.entry:param_bridge_node",
            f"judge_node = {PACKAGE}.entry:judge_node",
        ],
    },
)
