"""Speculation in the optimizer node: the same run, decision times in the bag."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from localpbo_ros.bagtools import load_run
from localpbo_ros.commands import main as cli_main
from localpbo_ros.driver import Driver
from localpbo_ros.suite import run_suite

from localpbo_msgs_py import DuelOutcome

from .configs import run_config

SETTINGS = {
    "run_id": "spec",
    "algorithm": "turpbo",
    "task": "swimmer",
    "task_options": json.dumps({"episode_steps": 40, "value_range": 50.0}),
    "seed": 2,
    "budget": 10,
}


def test_speculating_node_records_the_same_run_with_decision_times(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    plain = run_suite(dict(SETTINGS), tmp_path / "plain.mcap", timeout_s=120)
    fast = run_suite({**SETTINGS, "speculate": True}, tmp_path / "fast.mcap", timeout_s=120)
    assert plain.state == fast.state == "done"
    a, b = load_run(tmp_path / "plain.mcap"), load_run(tmp_path / "fast.mcap")
    assert {k: c.theta for k, c in a.candidates.items()} == {
        k: c.theta for k, c in b.candidates.items()
    }
    assert [(o.duel_id, o.winner_id) for o in a.outcomes] == [
        (o.duel_id, o.winner_id) for o in b.outcomes
    ]
    for run in (a, b):
        seconds = [r.decision_seconds for r in run.requests.values()]
        assert len(seconds) == 9 and all(s is not None and 0 <= s < 60 for s in seconds)
    assert cli_main(["bag-info", str(tmp_path / "fast.mcap")]) == 0
    assert "decision time: 9 duels, median " in capsys.readouterr().out


def test_driver_adopts_the_prepared_branch() -> None:
    config = run_config(run_id="d", algorithm="turpbo", task="hartmann6", seed=4, budget=8)
    plain, fast = Driver(config), Driver(config)
    for driver in (plain, fast):
        driver.ask()
    while not plain.done:
        (req,) = plain.pending_requests()
        assert fast.pending_requests() == (req,)
        spec = fast.speculate()
        assert spec is not None
        spec.join()
        shown, expected = fast.prepared_recommendation(), plain.recommendation()
        assert (shown is None) == (expected is None)  # None before the first answer
        assert shown is None or expected is None or shown.candidate_id == expected.candidate_id
        answer = DuelOutcome.decisive(req, req.second_id if req.duel_id % 3 else req.first_id)
        assert plain.offer(answer).accepted and fast.offer(answer).accepted
        assert fast.step_open == plain.step_open
        assert fast.pending_requests() == plain.pending_requests()
        if plain.done:
            break
        assert plain.ask() == fast.ask()
    assert fast.done and fast.speculated == plain.n_duels
    assert [c.theta.tobytes() for c in fast.session.optimizer.history.candidates] == [
        c.theta.tobytes() for c in plain.session.optimizer.history.candidates
    ]


def test_an_answer_to_nothing_prepared_is_decided_as_usual() -> None:
    config = run_config(run_id="d", algorithm="sobol", task="hartmann6", seed=1, budget=5)
    driver = Driver(config)
    driver.ask()
    (req,) = driver.pending_requests()
    assert driver.speculate() is not None
    driver.cancel_speculation()
    assert driver.offer(DuelOutcome.decisive(req, req.first_id)).accepted
    assert driver.speculated == 0 and len(driver.ask().candidates) == 1
