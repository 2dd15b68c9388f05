"""Speculation in the optimizer node: the same run, decision times in the bag."""

from __future__ import annotations

import json
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from localpbo_ros.bagtools import load_run
from localpbo_ros.commands import main as cli_main
from localpbo_ros.driver import Driver
from localpbo_ros.sim_node import SimNode
from localpbo_ros.suite import run_suite

from localpbo_core.problems import make_problem
from localpbo_core.seeds import episode_seed
from localpbo_msgs_py import CandidateMsg, DuelOutcome, EpisodeResult, RunConfig, Status
from localpbo_msgs_py.bag import read_messages
from localpbo_msgs_py.topics import (
    ALL_TOPICS,
    CANDIDATE,
    EPISODE_RESULT,
    RUN_CONFIG,
    SPECULATIVE_CANDIDATE,
    STATUS,
)

from . import person
from .configs import run_config
from .judged_suite import JudgedSuite

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
    # episodes run ahead: the same returns, nothing speculative in the bag, and used
    assert _returns(tmp_path / "plain.mcap") == _returns(tmp_path / "fast.mcap")
    for bag in ("plain.mcap", "fast.mcap"):
        assert _topics(tmp_path / bag) <= {t.name for t in ALL_TOPICS}
    assert cli_main(["bag-info", str(tmp_path / "fast.mcap")]) == 0
    assert "decision time: 9 duels, median " in capsys.readouterr().out


def _judged(tmp_path: Path, name: str, speculate: bool, undo_at: int = -1) -> Path:
    """A run answered by a scripted person 0.3 s after each duel is ready (``a``, every third
    answer ``tie``); at answer ``undo_at`` the person first answers ``b``, then takes it back
    and answers as usual."""
    bag = tmp_path / f"{name}.mcap"
    settings = {**SETTINGS, "run_id": name, "speculate": speculate, "tie_threshold": 0.25}
    judge = {"state_dir": str(tmp_path / f"judge-{name}")}
    run = JudgedSuite(settings, bag, judge, url_timeout_s=60, timeout_s=300)
    url = run.url
    duel = person.next_ready(url)
    n = 0
    while duel is not None:
        time.sleep(0.3)
        did = duel["duel_id"]
        if n == undo_at:
            assert person.answer(url, duel, "b")[0] == 200
            code, body = person.undo(url, did)
            assert code == 200, body
            # the duel is asked again, under its id (the next duel of the taken-back answer
            # may show until the optimizer's re-request arrives)
            end = time.monotonic() + 120
            again = person.next_ready(url)
            while again is not None and again["duel_id"] != did and time.monotonic() < end:
                time.sleep(0.05)
                again = person.next_ready(url)
            assert again is not None and again["duel_id"] == did
            time.sleep(0.3)
        assert person.answer(url, duel, "tie" if n % 3 == 2 else "a")[0] == 200
        n += 1
        duel = person.next_ready(url, after=did)
    summary = run.finish(120)
    assert summary.state == "done", summary.error
    return bag


def test_episodes_run_ahead_while_a_person_watches(tmp_path: Path) -> None:
    plain = _judged(tmp_path, "plain", speculate=False)
    fast = _judged(tmp_path, "fast", speculate=True)
    a, b = load_run(plain), load_run(fast)
    assert {k: c.theta for k, c in a.candidates.items()} == {
        k: c.theta for k, c in b.candidates.items()
    }
    assert [(o.duel_id, o.kind, o.winner_id) for o in a.outcomes] == [
        (o.duel_id, o.kind, o.winner_id) for o in b.outcomes
    ]
    assert _returns(plain) == _returns(fast)
    assert _topics(fast) <= {t.name for t in ALL_TOPICS}  # nothing speculative recorded
    assert _sim_counters(plain).get("episodes_ahead", 0) == 0
    # how many were used depends on the machine's speed (the benchmark prints it)
    print("episodes run ahead:", _sim_counters(fast))


def test_sim_node_answers_a_candidate_run_ahead_at_once(ros) -> None:
    config = run_config(run_id="ahead", algorithm="sobol", task="hartmann6", seed=4, budget=8)
    calls: list[int] = []
    problem = make_problem("hartmann6")

    def evaluator(c: RunConfig, cid: int, native: np.ndarray) -> float:
        calls.append(cid)
        if cid == 5:
            raise RuntimeError("exploded")
        return float(problem.evaluate_native(native, seed=episode_seed(c.seed, cid)))

    sim = ros.add(SimNode(context=ros.ctx, evaluator=evaluator))
    results = ros.collect(EPISODE_RESULT)
    ros.publish(RUN_CONFIG, config.encode())
    assert ros.spin_until(lambda: sim.config is not None, 5)
    theta = {k: tuple(float(v) for v in np.full(6, 0.1 * k)) for k in range(4)}
    other = tuple(float(v) for v in np.full(6, 0.77))
    # branches propose candidate 1 with θ1 and with another θ; 5 fails ahead; 99 is foreign
    for cid, th in ((1, theta[1]), (1, other), (2, theta[2]), (5, theta[3]), (99, theta[3])):
        ros.publish(SPECULATIVE_CANDIDATE, CandidateMsg("ahead", cid, th).encode())
    assert ros.spin_until(
        lambda: (
            sim.counters["episodes_ahead"] == 3
            and sim.counters["episodes_ahead_failed"] == 1
            and sim.counters["dropped_id_out_of_range"] == 1
        ),
        10,
    )
    assert not results  # nothing published ahead
    assert sorted(calls) == [1, 1, 2, 5]
    # the real candidates: 1 with θ1 is answered from the episode run ahead, 3 is evaluated
    ros.publish(CANDIDATE, CandidateMsg("ahead", 1, theta[1]).encode())
    ros.publish(CANDIDATE, CandidateMsg("ahead", 3, theta[3]).encode())
    assert ros.spin_until(lambda: len(results) >= 2, 10)
    got = {r.candidate_id: r.episode_return for r in decode_all(EpisodeResult, results)}
    for cid in (1, 3):
        assert got[cid] == problem.evaluate_native(
            np.asarray(theta[cid]), seed=episode_seed(config.seed, cid)
        )
    assert sorted(calls) == [1, 1, 2, 3, 5]  # no second episode of candidate 1
    assert sim.counters["episodes_ahead_used"] == 1 and sim.counters["episodes"] == 2
    # a speculative θ for an id already asked is ignored
    ros.publish(SPECULATIVE_CANDIDATE, CandidateMsg("ahead", 3, other).encode())
    ros.spin_for(0.2)
    assert sim.counters["episodes_ahead"] == 3 and sorted(calls) == [1, 1, 2, 3, 5]


def test_branch_candidates_are_the_next_ask_of_that_answer() -> None:
    config = run_config(run_id="d", algorithm="turpbo", task="hartmann6", seed=4, budget=9)
    driver = Driver(config)
    driver.ask()
    checked = 0
    branches: dict[Any, Any] = {}
    while not driver.done:
        (req,) = driver.pending_requests()
        branches.clear()
        spec = driver.speculate(lambda b: branches.__setitem__(b.answer, b))
        assert spec is not None
        spec.join()
        answer = DuelOutcome.decisive(req, req.second_id if req.duel_id % 2 else req.first_id)
        assert driver.offer(answer).accepted
        if driver.done:
            break
        work = driver.ask()
        (branch,) = [b for a, b in branches.items() if a.winner == answer.winner_id]
        assert driver.branch_candidates(branch) == work.candidates
        checked += 1
    assert checked >= 3


def test_a_person_takes_an_answer_back_and_the_bag_verifies(tmp_path: Path) -> None:
    from localpbo_ros.replay import verify

    plain = _judged(tmp_path, "plain", speculate=True)
    undone = _judged(tmp_path, "undone", speculate=True, undo_at=4)
    run = load_run(undone)
    kinds = [o.kind.value for o in run.outcomes]
    assert kinds.count("retracted") == 1
    retracted = kinds.index("retracted")
    assert run.outcomes[retracted].duel_id == run.outcomes[retracted - 1].duel_id
    report = verify(undone)
    assert report.ok, report.format()
    # the run is the one that never got the retracted answer: same θ, one id spent
    kept = [c.theta for _, c in sorted(load_run(plain).candidates.items())]
    ids = sorted(run.candidates)
    assert len(ids) == len(kept) + 1
    rebuilt = [run.candidates[i].theta for i in ids]
    assert [t for t in rebuilt if t in kept] == kept


def decode_all(cls, msgs):  # type: ignore[no-untyped-def]
    return [cls.decode(m) for m in msgs]


def _returns(bag: Path) -> dict[int, float | None]:
    out: dict[int, float | None] = {}
    for rec in read_messages(bag):
        if rec.topic == EPISODE_RESULT.name:
            res = EpisodeResult.decode(rec.message)
            assert isinstance(res, EpisodeResult)
            out.setdefault(res.candidate_id, res.episode_return)
    return out


def _topics(bag: Path) -> set[str]:
    return {rec.topic for rec in read_messages(bag)}


def _sim_counters(bag: Path) -> dict[str, int]:
    """The sim node's last counters recorded in the bag."""
    last: dict[str, int] = {}
    for rec in read_messages(bag):
        if rec.topic == STATUS.name:
            status = Status.decode(rec.message)
            if isinstance(status, Status) and status.node == "sim_node":
                last = dict(status.counters)
    return last


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


def test_judge_replays_the_episodes_of_speculative_candidates_ahead(ros, tmp_path: Path) -> None:
    from localpbo_ros.judge_node import JudgeNode
    from localpbo_ros.rollouts import RolloutCache

    task = {"episode_steps": 40, "value_range": 50.0}
    config = run_config(
        run_id="ahead", algorithm="sobol", task="swimmer", seed=3, budget=8, task_options=task
    )
    judge = ros.add(JudgeNode(context=ros.ctx, overrides={"state_dir": str(tmp_path)}))
    ros.publish(RUN_CONFIG, config.encode())
    assert ros.spin_until(lambda: judge._rollouts is not None, 10)
    rollouts = judge._rollouts
    assert rollouts is not None
    box = make_problem("swimmer", **task)
    theta = {k: tuple(float(v) for v in box.to_native(np.full(box.dim, 0.2 * k))) for k in (1, 2)}
    # two branches propose candidate 4 with different θ: both replays are kept
    for th in (theta[1], theta[2]):
        ros.publish(SPECULATIVE_CANDIDATE, CandidateMsg("ahead", 4, th).encode())
    ros.publish(SPECULATIVE_CANDIDATE, CandidateMsg("ahead", 999, theta[1]).encode())
    assert ros.spin_until(lambda: rollouts.episodes == 2, 20)
    assert judge.counters["dropped_id_out_of_range"] == 1
    ros.publish(CANDIDATE, CandidateMsg("ahead", 4, theta[2]).encode())
    assert ros.spin_until(lambda: 4 in judge.core.candidates, 10)
    shown = judge.rollout(4)
    assert rollouts.episodes == 2  # the page's request is served from the replay ahead
    fresh = RolloutCache(box, config.seed, stride=judge.settings["frame_stride"], max_entries=0)
    assert shown == fresh.get(4, theta[2])
