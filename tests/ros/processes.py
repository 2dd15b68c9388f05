"""Node executables as subprocesses, for tests of what a ``ros2 run`` user sees."""

from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
import time
from collections.abc import Sequence
from pathlib import Path

from localpbo_msgs_py import Status
from localpbo_msgs_py.bag import read_messages
from localpbo_msgs_py.topics import STATUS

HEAVY = ("numpy", "torch", "rclpy", "mujoco")
"""Shared objects of the heavy imports (their paths contain these names)."""


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
    env["PYTHONFAULTHANDLER"] = "1"  # SIGABRT prints every thread's stack (see stop_nodes)
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


def interrupt(proc: subprocess.Popen[str], timeout_s: float) -> None:
    """Stop ``proc`` with SIGINT; kill it if it has not ended within ``timeout_s``."""
    proc.send_signal(signal.SIGINT)
    try:
        proc.wait(timeout_s)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait()


def wait_heard(bag: Path, nodes: set[str], timeout_s: float = 60.0) -> None:
    """Until the recorder has recorded a status of each of ``nodes`` in ``bag``."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        heard = set()
        if bag.exists():
            for rec in read_messages(bag, topics=[STATUS.name]):
                status = Status.decode(rec.message)
                if isinstance(status, Status):
                    heard.add(status.node)
        if nodes <= heard:
            return
        time.sleep(0.1)
    raise AssertionError(f"the recorder did not hear {nodes}")


def run_sobol(
    env: dict[str, str], run_id: str, budget: int, timeout_s: float
) -> subprocess.CompletedProcess[str]:
    """Run a Sobol optimizer node process through a run of ``budget`` short episodes
    (50 steps) that waits for two subscribers (simulator and oracle)."""
    return subprocess.run(
        [
            sys.executable,
            "-m",
            "localpbo_ros.optimizer_node",
            "--ros-args",
            "-p",
            "algorithm:=sobol",
            "-p",
            f"budget:={budget}",
            "-p",
            f"run_id:={run_id}",
            "-p",
            "min_subscribers:=2",
            "-p",
            'task_options:=\'{"episode_steps": 50, "value_range": 50.0}\'',
        ],
        env=env,
        capture_output=True,
        text=True,
        timeout=timeout_s,
    )


def stop_nodes(procs: Sequence[subprocess.Popen[str]], timeout_s: float = 30.0) -> list[int]:
    """Send SIGINT to every process and wait for all of them; return their exit codes.

    Each one's stderr is read while waiting, so a chatty node cannot block on a full pipe.
    A process still running after ``timeout_s`` gets SIGABRT (with ``PYTHONFAULTHANDLER``, as
    ``host_env`` sets it, Python prints where every thread was) and the test fails with what
    that process wrote.
    """
    for proc in procs:
        if proc.poll() is None:
            proc.send_signal(signal.SIGINT)
    deadline = time.monotonic() + timeout_s
    codes = []
    for proc in procs:
        try:
            _, err = proc.communicate(timeout=max(deadline - time.monotonic(), 0.1))
        except subprocess.TimeoutExpired:
            proc.send_signal(signal.SIGABRT)
            _, err = proc.communicate(timeout=30)
            for other in procs:
                if other.poll() is None:
                    other.kill()
                    other.wait()
            raise AssertionError(
                f"{proc.args} still running {timeout_s} s after SIGINT; stderr:\n{err}"
            ) from None
        if proc.returncode != 0:
            raise AssertionError(f"{proc.args} exited with {proc.returncode}; stderr:\n{err}")
        codes.append(proc.returncode)
    return codes


def wait_for_guard(pid: int, timeout: float = 60.0) -> None:
    """Wait until process ``pid`` catches SIGTERM: its start guard is in place (Python itself
    catches only SIGINT)."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        try:
            status = Path(f"/proc/{pid}/status").read_text()
        except (FileNotFoundError, ProcessLookupError):
            raise AssertionError(f"process {pid} ended before its guard was seen") from None
        caught = re.search(r"SigCgt:\s*([0-9a-f]+)", status)
        if caught and int(caught.group(1), 16) & (1 << (signal.SIGTERM - 1)):
            return
        time.sleep(0.001)
    raise AssertionError(f"process {pid} never caught SIGTERM")


IMPORT_LINE = re.compile(r"^import time:\s*\d+ \|\s*\d+ \|(\s*)(\S+)", re.MULTILINE)


def imported_before_guard(stderr: str) -> list[str]:
    """The heavy modules a process imported before the stop guard's module
    (``localpbo_core.stopping``), from its ``PYTHONPROFILEIMPORTTIME=1`` report on stderr.

    The report lists a module when its import completes, nested imports first, so a heavy
    module imported by the guard's own import chain would be listed before it.
    """
    names = [m.group(2) for m in IMPORT_LINE.finditer(stderr)]
    assert "localpbo_core.stopping" in names, stderr[-3000:]
    before = names[: names.index("localpbo_core.stopping")]
    return sorted({n for n in before if n.split(".")[0] in HEAVY})
