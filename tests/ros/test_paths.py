"""The run protocol's contract: the same algorithm, task, seed, budget and noise give
bit-identical candidates, duel outcomes and episode returns in ``localpbo bench``, in
``localpbo run`` (one process) and in four separate node processes."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import pytest
from localpbo_ros.suite import run_suite

from localpbo_msgs_py import Status
from localpbo_msgs_py.bag import read_messages
from localpbo_msgs_py.topics import STATUS

from . import same_run


def node_parameters() -> dict[str, Any]:
    return {
        "run_id": "paths",
        "algorithm": same_run.ALGORITHM,
        "algorithm_options": json.dumps(same_run.OPTIONS),
        "task": same_run.TASK,
        "task_options": json.dumps(same_run.TASK_OPTIONS),
        "seed": same_run.SEED,
        "budget": same_run.BUDGET,
        "noise_fraction": same_run.NOISE,
    }


def from_four_processes(tmp_path: Path) -> dict[str, Any]:
    """Recorder, simulator, oracle and optimizer as separate processes (loopback DDS)."""
    env = {
        k: v
        for k, v in os.environ.items()
        if k not in ("ROS_AUTOMATIC_DISCOVERY_RANGE", "FASTRTPS_DEFAULT_PROFILES_FILE")
    }
    env["ROS_DOMAIN_ID"] = "61"
    bag = tmp_path / "four.mcap"

    def start(module: str, *ros_args: str) -> subprocess.Popen[str]:
        cmd = [sys.executable, "-m", f"localpbo_ros.{module}", "--ros-args", *ros_args]
        return subprocess.Popen(
            cmd, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True
        )

    helpers = [
        start("recorder_node", "-p", f"path:={bag}"),
        start("sim_node", "-p", "run_id:=paths"),
        start("oracle_node", "-p", "run_id:=paths"),
    ]
    try:
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline:  # the recorder hears both followers: discovery done
            heard = set()
            if bag.exists():
                for rec in read_messages(bag, topics=[STATUS.name]):
                    status = Status.decode(rec.message)
                    if isinstance(status, Status) and status.node != "recorder_node":
                        heard.add(status.node)
            if len(heard) >= 2:
                break
            time.sleep(0.1)
        args = ["-p", "min_subscribers:=2"]
        for key, value in node_parameters().items():
            text = f"'{value}'" if isinstance(value, str) and value.startswith("{") else value
            args += ["-p", f"{key}:={text}"]
        opt = subprocess.run(
            [sys.executable, "-m", "localpbo_ros.optimizer_node", "--ros-args", *args],
            env=env,
            capture_output=True,
            text=True,
            timeout=300,
        )
        assert opt.returncode == 0, opt.stderr
        # the node logs progress and, at the end, the summary that localpbo run prints
        assert "10 duels, " in opt.stderr
        assert "run paths: done" in opt.stderr
        assert "recommended candidate (highest posterior mean utility" in opt.stderr
    finally:
        for proc in helpers:
            proc.send_signal(signal.SIGINT)
        for proc in helpers:
            proc.wait(30)
    return same_run.from_bag(bag)


@pytest.mark.slow
def test_bench_run_and_four_processes_give_the_same_run(tmp_path: Path) -> None:
    reference = same_run.from_bench(tmp_path)
    assert len(reference["native"]) == same_run.BUDGET
    assert len(reference["answers"]) >= same_run.BUDGET - 1
    assert {kind for _, _, kind, _ in reference["answers"].values()} == {"decisive"}

    one_process = tmp_path / "one.mcap"
    summary = run_suite(node_parameters(), one_process, timeout_s=300)
    assert summary.state == "done", summary.error
    paths = {
        "localpbo run": same_run.from_bag(one_process),
        "four processes": from_four_processes(tmp_path),
    }

    for name, got in paths.items():
        # floats compared exactly: bit-identical, not approximately equal
        assert got["native"] == reference["native"], name
        assert got["values"] == reference["values"], name
        assert got["answers"] == reference["answers"], name
