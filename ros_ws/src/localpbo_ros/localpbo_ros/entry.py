"""Process entry for the executables: DDS scope, rclpy init, clear parameter errors, spin.

Stopping: the first SIGINT or SIGTERM asks the node to stop; it leaves its spin loop, closes
what it holds (the recorder finishes its bag) and exits 0. Further signals are ignored until
the process has exited, so a second Ctrl-C, or ``timeout``/a process-group kill signalling
twice, cannot cut the clean-up short with a traceback or a death by signal. rclpy's own signal
handlers are not installed for that reason (they shut the context down at the first signal and
leave the second to Python's default handler). Once the node is closed the signals are set to
be ignored.

Exiting is bounded. Once the spin loop has ended, the clean-up (closing the node, destroying it,
shutting the DDS participant down) has ``STOP_GRACE_S`` seconds plus the node's
``close_timeout_s`` (if it has one: the time its ``close`` may wait on purpose); should it
hang, ``faulthandler`` prints every thread's stack to stderr and the process exits with code 1
instead of waiting forever. After the clean-up the process leaves with ``os._exit``:
everything it holds is closed by then, and skipping the interpreter's finalization skips the
DDS library's static destructors, which are known to hang now and then at exit.
"""

from __future__ import annotations

import ctypes
import faulthandler
import os
import signal
import sys
import threading
import time
from collections.abc import Callable
from types import FrameType
from typing import Any, NoReturn

from localpbo_ros.dds import host_scope
from localpbo_ros.params import ParameterError

LINGER_S = 1.0
"""Seconds a finished optimizer keeps spinning so the last messages reach their readers."""

STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM)

STOP_GRACE_S = 20.0
"""Seconds the clean-up after the spin loop may take, beyond a node's own ``close_timeout_s``,
before the process reports where it hangs (every thread's stack on stderr) and exits with
code 1."""


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
) -> NoReturn:
    """Create one node from ``factory``, spin it until SIGINT (or until it finishes), and exit
    the process.

    Exit codes: 0 after a clean stop, 1 when the node's run failed or its clean-up hung past
    ``STOP_GRACE_S``, 2 when a parameter was refused (the message names it).
    """
    host_scope()
    code = _run(factory, argv, stop_when_finished, stop_on_signals())
    for sig in STOP_SIGNALS:  # the process only exits from here on
        signal.signal(sig, signal.SIG_IGN)
    exit_now(code)


def exit_now(code: int) -> NoReturn:
    """Flush Python's and C's output buffers and end the process with ``code`` at once,
    without the interpreter's finalization (see the module docstring)."""
    sys.stdout.flush()
    sys.stderr.flush()
    ctypes.CDLL(None).fflush(None)  # rcutils may log to a buffered C stdout
    os._exit(code)


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
        # a node whose close() may wait on purpose (the bridge restoring parameters) says how
        # long in ``close_timeout_s``; the watchdog adds it to the grace
        grace = STOP_GRACE_S + float(getattr(node, "close_timeout_s", 0.0))
        faulthandler.dump_traceback_later(grace, exit=True)
        if node is not None:
            if hasattr(node, "close"):
                node.close()
            node.destroy_node()
        if rclpy.ok():
            rclpy.shutdown()
    return code
