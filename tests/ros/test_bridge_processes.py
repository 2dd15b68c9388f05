"""The worked example tuned by separate processes (as with ``ros2 run``), and the target's
original gains back after the bridge is stopped with SIGINT mid-run (seen in the
controller's own log of parameter changes)."""

from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
import threading
from pathlib import Path
from typing import IO

from localpbo_examples.pid_controller_node import BRIDGE_SETTINGS
from localpbo_ros.replay import verify

from .processes import interrupt

REPO = Path(__file__).resolve().parents[2]
PID_SPACE = REPO / "ros_ws/src/localpbo_examples/config/pid_space.yaml"
ORIGINAL_LINE = "gains set: kp=1.0, ki=0.1, kd=0.1"
GAINS = re.compile(r"gains set: (kp=.*)")


class Proc:
    """A node process whose output is read on a thread (so pipes never fill)."""

    def __init__(self, module: str, env: dict[str, str], *ros_args: str) -> None:
        cmd = [sys.executable, "-m", module, "--ros-args", *ros_args]
        self.popen = subprocess.Popen(
            cmd, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True
        )
        self.lines: list[str] = []
        self.changed = threading.Condition()
        assert self.popen.stdout is not None
        threading.Thread(target=self._read, args=(self.popen.stdout,), daemon=True).start()

    def _read(self, stream: IO[str]) -> None:
        for line in stream:
            with self.changed:
                self.lines.append(line)
                self.changed.notify_all()

    def wait_for(self, pattern: str, count: int = 1, timeout: float = 120.0) -> bool:
        with self.changed:
            return self.changed.wait_for(
                lambda: sum(pattern in line for line in self.lines) >= count, timeout
            )

    def text(self) -> str:
        return "".join(self.lines)

    def stop(self) -> None:
        if self.popen.poll() is None:
            interrupt(self.popen, 20)


def environment() -> dict[str, str]:
    skip = ("ROS_AUTOMATIC_DISCOVERY_RANGE", "FASTRTPS_DEFAULT_PROFILES_FILE", "LOCALPBO_DDS_OPEN")
    env = {k: v for k, v in os.environ.items() if k not in skip}
    env["ROS_DOMAIN_ID"] = "91"
    return env


def bridge_args(**extra: str) -> list[str]:
    args: list[str] = []
    for key, value in {**BRIDGE_SETTINGS, **extra}.items():
        args += ["-p", f"{key}:={value}"]
    return args


def gain_lines(proc: Proc) -> list[str]:
    return [m.group(0) for m in map(GAINS.search, proc.lines) if m]


def test_separate_processes_tune_the_example(tmp_path: Path) -> None:
    env = environment()
    bag = tmp_path / "pid.mcap"
    procs = [
        Proc("localpbo_examples.pid_controller_node", env),
        Proc("localpbo_ros.recorder_node", env, "-p", f"path:={bag}"),
        Proc("localpbo_ros.oracle_node", env),
        Proc("localpbo_ros.param_bridge_node", env, *bridge_args()),
    ]
    controller, recorder, _, bridge = procs
    try:
        for proc in procs:
            assert proc.wait_for(" ready"), proc.text()
        optimizer = Proc(
            "localpbo_ros.optimizer_node",
            env,
            *("-p", f"space:={PID_SPACE}", "-p", "budget:=12", "-p", "run_id:=mp"),
            *("-p", "min_subscribers:=2", "-p", "algorithm:=sobol"),
        )
        procs.append(optimizer)
        assert optimizer.popen.wait(180) == 0, optimizer.text()
        assert bridge.wait_for("restoring the target"), bridge.text()
        assert controller.wait_for(ORIGINAL_LINE), controller.text()
        assert gain_lines(controller)[-1] == ORIGINAL_LINE
        assert len(gain_lines(controller)) == 13  # 12 candidates, then the originals
    finally:
        for proc in reversed(procs):
            proc.stop()
    assert recorder.popen.returncode == 0
    report = verify(bag)
    assert report.ok and report.candidates_checked == 12, report.format()


def test_sigint_to_the_bridge_restores_the_target(tmp_path: Path) -> None:
    env = environment()
    env["ROS_DOMAIN_ID"] = "92"
    procs = [
        # slow episodes (3 s each), so the run is surely in its middle when stopped
        Proc("localpbo_examples.pid_controller_node", env, "-p", "rate_hz:=10.0"),
        Proc("localpbo_ros.oracle_node", env),
        Proc("localpbo_ros.param_bridge_node", env, *bridge_args()),
    ]
    controller, _, bridge = procs
    try:
        for proc in procs:
            assert proc.wait_for(" ready"), proc.text()
        procs.append(
            Proc(
                "localpbo_ros.optimizer_node",
                env,
                *("-p", f"space:={PID_SPACE}", "-p", "budget:=30", "-p", "run_id:=sig"),
                *("-p", "algorithm:=sobol"),
            )
        )
        assert controller.wait_for("gains set: kp="), controller.text()
        assert gain_lines(controller)[0] != ORIGINAL_LINE
        bridge.popen.send_signal(signal.SIGINT)
        assert bridge.popen.wait(30) == 0, bridge.text()
        assert "restored the original parameters" in bridge.text(), bridge.text()
        assert controller.wait_for(ORIGINAL_LINE), controller.text()
        assert gain_lines(controller)[-1] == ORIGINAL_LINE
        assert "Traceback" not in bridge.text()
    finally:
        for proc in reversed(procs):
            proc.stop()
