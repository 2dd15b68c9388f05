"""Node executables as subprocesses, for tests of what a ``ros2 run`` user sees."""

from __future__ import annotations

import os
import subprocess
import sys


def wait_ready(proc: subprocess.Popen[str]) -> list[str]:
    """Read the node's output until it logs ``<name> ready``; return the lines read.

    Fails (with the output) if the process ends first. The process must have been started
    with ``stdout=PIPE, stderr=STDOUT, text=True``.
    """
    assert proc.stdout is not None
    lines = []
    for line in proc.stdout:
        lines.append(line)
        if " ready" in line:
            return lines
    raise AssertionError("node ended before it was ready:\n" + "".join(lines))


def host_env(domain_id: int) -> dict[str, str]:
    """This process's environment for node processes on ROS domain ``domain_id``, with the
    DDS settings the executables choose themselves (host-only discovery) left to them."""
    env = {
        k: v
        for k, v in os.environ.items()
        if k
        not in (
            "ROS_AUTOMATIC_DISCOVERY_RANGE",
            "FASTRTPS_DEFAULT_PROFILES_FILE",
            "LOCALPBO_DDS_OPEN",
        )
    }
    env["ROS_DOMAIN_ID"] = str(domain_id)
    return env


def start_node(env: dict[str, str], node: str, *ros_args: str) -> subprocess.Popen[str]:
    """Start ``python -m localpbo_ros.<node>`` (or the script ``node`` when it ends in
    ``.py``) with ``--ros-args ros_args``; stdout discarded, stderr piped."""
    if node.endswith(".py"):
        cmd = [sys.executable, node]
    else:
        cmd = [sys.executable, "-m", f"localpbo_ros.{node}"]
    if ros_args:
        cmd += ["--ros-args", *ros_args]
    return subprocess.Popen(
        cmd, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True
    )
