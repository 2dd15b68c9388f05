"""SIGKILL mid-run, then ``run --resume``: a complete run, each duel recorded exactly once."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from collections import Counter

from localpbo_ros.bagtools import load_run
from localpbo_ros.commands import main as cli_main
from localpbo_ros.replay import verify
from localpbo_ros.suite import run_suite

from localpbo_msgs_py import DuelOutcome, OutcomeKind
from localpbo_msgs_py.bag import read_messages
from localpbo_msgs_py.topics import DUEL_OUTCOME

BUDGET = 40
TASK = {"episode_steps": 1000}  # calibrated value range; ~50 ms per episode


def decisive_ids(path) -> Counter:
    ids: Counter = Counter()
    for rec in read_messages(path, topics=[DUEL_OUTCOME.name]):
        out = DuelOutcome.decode(rec.message)
        if isinstance(out, DuelOutcome) and out.kind is OutcomeKind.DECISIVE:
            ids[out.duel_id] += 1
    return ids


def test_sigkill_then_resume(tmp_path) -> None:
    bag = tmp_path / "killed.mcap"
    cmd = [
        sys.executable,
        "-m",
        "localpbo_ros.commands",
        "run",
        "--algorithm",
        "sobol",
        "--task",
        "swimmer",
        "--budget",
        str(BUDGET),
        "--seed",
        "7",
        "--run-id",
        "kill",
        "--task-options",
        json.dumps(TASK),
        "--bag",
        str(bag),
        "--no-progress",
    ]
    env = {**os.environ, "ROS_AUTOMATIC_DISCOVERY_RANGE": "OFF"}
    proc = subprocess.Popen(cmd, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT)
    try:
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline:
            if bag.exists() and len(decisive_ids(bag)) >= 10:
                break
            assert proc.poll() is None, proc.stdout.read().decode()
            time.sleep(0.05)
        proc.send_signal(signal.SIGKILL)
        proc.wait(10)
    finally:
        if proc.poll() is None:
            proc.kill()
    before = decisive_ids(bag)
    assert 10 <= len(before) < BUDGET - 1, "the kill must land mid-run"
    assert not load_run(bag).complete  # no footer: the writer was killed
    assert verify(bag).ok

    resumed = tmp_path / "resumed.mcap"
    code = cli_main(["run", "--resume", str(bag), "--bag", str(resumed), "--no-progress"])
    assert code == 0
    after = decisive_ids(resumed)
    assert sorted(after) == list(range(BUDGET - 1)) and set(after.values()) == {1}
    report = verify(resumed)
    assert report.ok and report.candidates_checked == BUDGET, report.format()

    # same outcomes as an uninterrupted run with the same settings (ids and winners)
    whole = tmp_path / "whole.mcap"
    summary = run_suite(
        {
            "algorithm": "sobol",
            "task": "swimmer",
            "budget": BUDGET,
            "seed": 7,
            "run_id": "kill",
            "task_options": json.dumps(TASK),
        },
        whole,
        timeout_s=120,
    )
    assert summary.state == "done"

    def winners(path):
        return sorted(
            (o.duel_id, o.winner_id)
            for o in load_run(path).outcomes
            if o.kind is OutcomeKind.DECISIVE
        )

    assert winners(resumed) == winners(whole)


def test_resume_of_a_complete_run_adds_no_duel(tmp_path) -> None:
    from pathlib import Path

    committed = Path(__file__).resolve().parents[2] / "bags" / "swimmer_sobol_s0.mcap"
    out = tmp_path / "again.mcap"
    summary = run_suite({}, out, resume=committed, timeout_s=60)
    assert summary.state == "done" and summary.duels == summary.resumed_duels == 39
    assert Counter(decisive_ids(out).values()) == Counter({1: 39})
    assert verify(out).ok
