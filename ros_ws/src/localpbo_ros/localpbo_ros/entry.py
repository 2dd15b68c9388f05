"""Process entry for the executables: DDS scope, rclpy init, clear parameter errors, spin.

Starting: each executable's console script (what ``ros2 run`` starts) is one of the launchers
at the end of this module. A launcher installs the stop guard
(:func:`localpbo_core.stopping.guard_start`) before it imports its node's module, which loads
rclpy, numpy and torch (one to two seconds on a loaded machine): a SIGINT or SIGTERM in that
window ends the process at once with code 0 and the line ``<executable>: stopped by SIGINT
while starting``; nothing is held yet. ``run_node`` then replaces the guard by the handling
below before it creates anything.

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

import faulthandler
import importlib
import signal
import sys
import threading
import time
from collections.abc import Callable
from typing import Any, NoReturn

from localpbo_core.stopping import STOP_SIGNALS, exit_now, guard_start, stop_on_signals
from localpbo_ros.dds import host_scope

__all__ = ["STOP_SIGNALS", "exit_now", "run_node", "stop_on_signals"]

LINGER_S = 1.0
"""Seconds a finished optimizer keeps spinning so the last messages reach their readers."""

STOP_GRACE_S = 20.0
"""Seconds the clean-up after the spin loop may take, beyond a node's own ``close_timeout_s``,
before the process reports where it hangs (every thread's stack on stderr) and exits with
code 1."""


def wants_help(argv: list[str]) -> bool:
    """``-h`` or ``--help`` among the process arguments before ``--ros-args``."""
    own = argv[1:]
    if "--ros-args" in own:
        own = own[: own.index("--ros-args")]
    return "-h" in own or "--help" in own


def usage(factory: Callable[..., Any]) -> str:
    """What ``--help`` prints for a node executable: how to pass its ROS parameters, and the
    first paragraph of its module's docstring (else of the node class's)."""
    main = sys.modules.get("__main__")
    spec = getattr(main, "__spec__", None)
    name = f"python -m {spec.name}" if spec is not None else sys.argv[0]
    doc = (getattr(main, "__doc__", None) or factory.__doc__ or "").strip().split("\n\n")[0]
    return (
        f"usage: {name} [--ros-args -p NAME:=VALUE ...]\n\n"
        f"{' '.join(doc.split())}\n\n"
        "Its settings are ROS parameters; list them with `ros2 param list` and "
        "`ros2 param describe` while the node runs. Exit codes: 0 after a clean stop, 1 when "
        "the run failed, 2 when a parameter was refused."
    )


def run_node(
    factory: Callable[..., Any], argv: list[str] | None, *, stop_when_finished: bool
) -> NoReturn:
    """Create one node from ``factory``, spin it until SIGINT (or until it finishes), and exit
    the process.

    Exit codes: 0 after a clean stop, 1 when the node's run failed or its clean-up hung past
    ``STOP_GRACE_S``, 2 when a parameter was refused (the message names it).
    """
    if wants_help(sys.argv if argv is None else argv):
        print(usage(factory))
        exit_now(0)
    stop = stop_on_signals()  # replaces the launcher's start guard
    host_scope()
    code = _run(factory, argv, stop_when_finished, stop)
    for sig in STOP_SIGNALS:  # the process only exits from here on
        signal.signal(sig, signal.SIG_IGN)
    exit_now(code)


def _run(
    factory: Callable[..., Any],
    argv: list[str] | None,
    stop_when_finished: bool,
    stop: threading.Event,
) -> int:
    import rclpy
    from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
    from rclpy.signals import SignalHandlerOptions

    from localpbo_ros.params import ParameterError

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


def launcher(module: str) -> Callable[[], NoReturn]:
    """The console script of the executable whose ``main`` is in ``module``: the stop guard
    first (exit code 0, as for any stop of a node), then the import of ``module`` and its
    ``main``."""
    name = module.rpartition(".")[2]

    def start() -> NoReturn:
        guard_start(name, lambda signum: 0)
        main: Callable[[], NoReturn] = importlib.import_module(module).main
        main()

    start.__name__ = start.__qualname__ = name
    start.__doc__ = f"``ros2 run`` ... ``{name}``: ``{module}.main`` behind the stop guard."
    return start


optimizer_node = launcher("localpbo_ros.optimizer_node")
sim_node = launcher("localpbo_ros.sim_node")
oracle_node = launcher("localpbo_ros.oracle_node")
recorder_node = launcher("localpbo_ros.recorder_node")
param_bridge_node = launcher("localpbo_ros.param_bridge_node")
judge_node = launcher("localpbo_ros.judge_node")
pid_controller_node = launcher("localpbo_examples.pid_controller_node")
