"""Process entry for the executables: DDS scope, rclpy init, clear parameter errors, spin.

Stopping: the first SIGINT or SIGTERM asks the node to stop; it leaves its spin loop, closes
what it holds (the recorder finishes its bag) and exits 0. Further signals are ignored until
the process has exited, so a second Ctrl-C, or ``timeout``/a process-group kill signalling
twice, cannot cut the clean-up short with a traceback or a death by signal. rclpy's own signal
handlers are not installed for that reason (they shut the context down at the first signal and
leave the second to Python's default handler). Once the node is closed the signals are set to
be ignored: Python's finalization (a few hundred ms with the DDS threads to end) resets every
Python-level handler to the default, under which a late signal would kill the process.
"""

from __future__ import annotations

import signal
import sys
import threading
import time
from collections.abc import Callable
from types import FrameType
from typing import Any

from localpbo_ros.dds import host_scope
from localpbo_ros.params import ParameterError

LINGER_S = 1.0
"""Seconds a finished optimizer keeps spinning so the last messages reach their readers."""

STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM)


def stop_on_signals() -> threading.Event:
    """Install handlers for SIGINT/SIGTERM (for the rest of the process); the returned event
    is set by the first signal, later ones change nothing."""
    requested = threading.Event()

    def handler(signum: int, frame: FrameType | None) -> None:
        requested.set()

    for sig in STOP_SIGNALS:
        signal.signal(sig, handler)
    return requested


def run_node(
    factory: Callable[..., Any], argv: list[str] | None, *, stop_when_finished: bool
) -> int:
    """Create one node from ``factory`` and spin it until SIGINT (or until it finishes).

    Returns the exit code: 0 after a clean stop, 1 when the node's run failed, 2 when a
    parameter was refused (the message names it).
    """
    host_scope()
    code = _run(factory, argv, stop_when_finished, stop_on_signals())
    for sig in STOP_SIGNALS:  # the process only exits from here on
        signal.signal(sig, signal.SIG_IGN)
    return code


def _run(
    factory: Callable[..., Any],
    argv: list[str] | None,
    stop_when_finished: bool,
    stop: threading.Event,
) -> int:
    import rclpy
    from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
    from rclpy.signals import SignalHandlerOptions

    args = sys.argv if argv is None else argv
    try:
        rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
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
        while rclpy.ok() and not stop.is_set():
            executor.spin_once(timeout_sec=0.1)
            if stop_when_finished and getattr(node, "finished", False):
                code = 1 if getattr(node, "error", "") else 0
                linger = time.monotonic() + LINGER_S  # deliver the last messages
                while rclpy.ok() and not stop.is_set() and time.monotonic() < linger:
                    executor.spin_once(timeout_sec=0.05)
                break
        if stop.is_set():
            node.get_logger().info(f"{node.get_name()} stopping on signal")
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
