"""Process entry for the executables: DDS scope, rclpy init, clear parameter errors, spin."""

from __future__ import annotations

import sys
import time
from collections.abc import Callable
from typing import Any

from localpbo_ros.dds import host_scope
from localpbo_ros.params import ParameterError

LINGER_S = 1.0
"""Seconds a finished optimizer keeps spinning so the last messages reach their readers."""


def run_node(
    factory: Callable[..., Any], argv: list[str] | None, *, stop_when_finished: bool
) -> int:
    """Create one node from ``factory`` and spin it until SIGINT (or until it finishes).

    Returns the exit code: 0 after a clean stop, 1 when the node's run failed, 2 when a
    parameter was refused (the message names it).
    """
    host_scope()
    import rclpy
    from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor

    args = sys.argv if argv is None else argv
    try:
        rclpy.init(args=args)
    except Exception as exc:  # rcl refuses malformed --ros-args (e.g. unquoted JSON)
        print(
            f"{factory.__name__}: cannot parse ROS arguments: {exc}\n"
            "hint: quote JSON parameters as YAML strings, e.g. "
            '-p "task_options:=\'{\\"episode_steps\\": 200}\'"',
            file=sys.stderr,
        )
        return 2
    node = None
    code = 0
    try:
        try:
            node = factory()  # parameters come from the global --ros-args
        except ParameterError as exc:
            print(f"{factory.__name__}: {exc}", file=sys.stderr)
            return 2
        node.get_logger().info(f"{node.get_name()} ready")
        executor = SingleThreadedExecutor()
        executor.add_node(node)
        while rclpy.ok():
            executor.spin_once(timeout_sec=0.1)
            if stop_when_finished and getattr(node, "finished", False):
                code = 1 if getattr(node, "error", "") else 0
                linger = time.monotonic() + LINGER_S  # deliver the last messages
                while rclpy.ok() and time.monotonic() < linger:
                    executor.spin_once(timeout_sec=0.05)
                break
    except (KeyboardInterrupt, ExternalShutdownException):
        code = 0
    finally:
        if node is not None:
            if hasattr(node, "close"):
                node.close()
            node.destroy_node()
        if rclpy.ok():
            rclpy.shutdown()
    return code
