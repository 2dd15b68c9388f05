"""Stopping an executable with two signals (a second Ctrl-C, ``timeout``, a process-group kill):
no traceback, exit 0, and the recorder's bag closed as complete. Signalled while it is still
importing (its console script, as ``ros2 run`` starts it): the same."""

from __future__ import annotations

import os
import random
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import pytest

from localpbo_msgs_py.bag import summarize

from .processes import imported_before_guard, wait_for_guard, wait_ready


def _start(cmd: list[str], bag: Path | None, **extra_env: str) -> subprocess.Popen[str]:
    """Start ``cmd`` on a host-only domain (with ``--ros-args -p path:=<bag>`` for a recorder),
    stdout and stderr merged into one pipe."""
    env = {
        **os.environ,
        "ROS_AUTOMATIC_DISCOVERY_RANGE": "OFF",
        "ROS_DOMAIN_ID": "62",
        **extra_env,
    }
    if bag is not None:
        cmd = [*cmd, "--ros-args", "-p", f"path:={bag}"]
    return subprocess.Popen(
        cmd, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True
    )


@contextmanager
def _running(cmd: list[str], bag: Path | None, **extra_env: str) -> Iterator[subprocess.Popen[str]]:
    """:func:`_start` ``cmd``; killed on leaving if it has not ended by then."""
    proc = _start(cmd, bag, **extra_env)
    try:
        yield proc
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()


@pytest.mark.parametrize(
    ("module", "second", "gap_s"),
    [
        *[("recorder_node", signal.SIGINT, gap_s) for gap_s in (0.0, 0.03, 0.1)],
        ("recorder_node", signal.SIGTERM, 0.05),
        ("sim_node", signal.SIGINT, 0.05),
    ],
)
def test_second_signal_still_stops_cleanly(
    module: str, second: signal.Signals, gap_s: float, tmp_path: Path
) -> None:
    bag = tmp_path / "sig.mcap"
    with _running(
        [sys.executable, "-m", f"localpbo_ros.{module}"],
        bag if module == "recorder_node" else None,
    ) as proc:
        lines = wait_ready(proc)
        proc.send_signal(signal.SIGINT)
        time.sleep(gap_s)
        proc.send_signal(second)
        out = "".join(lines) + proc.stdout.read()
        code = proc.wait(30)
    assert code == 0, out
    assert "Traceback" not in out, out
    if module == "recorder_node":
        assert summarize(bag).complete


def test_output_logged_while_stopping_is_not_lost(tmp_path: Path) -> None:
    proc = _start([sys.executable, "-m", "localpbo_ros.recorder_node"], tmp_path / "stop.mcap")
    lines = wait_ready(proc)
    proc.send_signal(signal.SIGINT)
    out, _ = proc.communicate(timeout=30)
    assert proc.returncode == 0, out
    assert "recorder_node stopping on signal" in "".join(lines) + out


def test_clean_up_that_hangs_is_reported_and_ended(tmp_path: Path) -> None:
    script = str(Path(__file__).with_name("hanging_close.py"))
    with _running([sys.executable, script], tmp_path / "stop.mcap") as proc:
        wait_ready(proc)
        proc.send_signal(signal.SIGINT)
        start = time.monotonic()
        out, _ = proc.communicate(timeout=30)
        took = time.monotonic() - start
    # STOP_GRACE_S is 2 s in the script: the watchdog ends the process, code 1, and the stack
    # it prints shows where the clean-up hung
    assert proc.returncode == 1, out
    assert 1.5 < took < 20.0
    assert "Timeout" in out and "in close" in out, out


def test_a_node_may_take_its_declared_close_timeout(tmp_path: Path) -> None:
    # close() sleeps 3 s, beyond the script's 2 s grace but within the 2 + 2 s the node
    # declares (as the bridge does for restoring parameters): a clean stop, the bag complete
    script = str(Path(__file__).with_name("hanging_close.py"))
    with _running(
        [sys.executable, script], tmp_path / "stop.mcap", CLOSE_SLEEP_S="3", CLOSE_TIMEOUT_S="2"
    ) as proc:
        wait_ready(proc)
        proc.send_signal(signal.SIGINT)
        out, _ = proc.communicate(timeout=30)
    assert proc.returncode == 0, out
    assert "Traceback" not in out and "Timeout" not in out, out
    assert summarize(tmp_path / "stop.mcap").complete


@pytest.mark.parametrize(
    ("exe", "sig", "seed"),
    [
        ("sim_node", signal.SIGINT, 0),
        ("sim_node", signal.SIGTERM, 1),
        ("optimizer_node", signal.SIGTERM, 2),
        ("recorder_node", signal.SIGINT, 3),
        ("param_bridge_node", signal.SIGTERM, 4),
        ("pid_controller_node", signal.SIGINT, 5),
    ],
)
def test_signal_while_importing_stops_cleanly(
    exe: str, sig: signal.Signals, seed: int, tmp_path: Path
) -> None:
    """The executable's console script (``localpbo_ros.entry.<exe>``) signalled at a random
    point of its first second (its imports of rclpy, numpy, torch): exit 0, no traceback."""
    rng = random.Random(seed)
    bag = tmp_path / "early.mcap"
    cmd = [sys.executable, "-c", f"from localpbo_ros.entry import {exe}; {exe}()"]
    if exe == "param_bridge_node":
        # its one required parameter: a start that gets past its imports before the signal
        # waits for its target instead of refusing its configuration (exit 2)
        cmd += ["--ros-args", "-p", "target_node:=/pid_controller_node"]
    with _running(
        cmd,
        bag if exe == "recorder_node" else None,
        PYTHONPROFILEIMPORTTIME="1",
    ) as proc:
        wait_for_guard(proc.pid)
        time.sleep(rng.uniform(0.0, 0.8))
        proc.send_signal(sig)
        out, _ = proc.communicate(timeout=60)
    assert proc.returncode == 0, out
    assert "Traceback" not in out, out
    assert imported_before_guard(out) == []  # the guard came before the heavy imports
    assert f"{exe}: stopped by {sig.name} while starting" in out or "stopping on signal" in out
    if exe == "recorder_node" and bag.exists():
        assert summarize(bag).complete
