"""A pool of evaluators: several sim_node workers share a run's candidates."""

from __future__ import annotations

import json
import time
from collections import Counter
from pathlib import Path
from typing import Any

from localpbo_ros.bagtools import load_run
from localpbo_ros.optimizer_node import OptimizerNode
from localpbo_ros.oracle_node import OracleNode
from localpbo_ros.pool import WorkerPool
from localpbo_ros.recorder_node import RecorderNode
from localpbo_ros.replay import verify
from localpbo_ros.sim_node import SimNode

from localpbo_core.problems import make_problem
from localpbo_core.seeds import episode_seed
from localpbo_msgs_py import CandidateMsg, DecodeError
from localpbo_msgs_py.bag import BagWriter
from localpbo_msgs_py.topics import DUEL_OUTCOME, EPISODE_RESULT

from .conftest import SMALL_TASK, Harness

SETTINGS = {
    "algorithm": "sobol",
    "algorithm_options": json.dumps({"batch_size": 4}),
    "task": "swimmer",
    "budget": 18,
    "seed": 5,
    "run_id": "pool",
    "task_options": json.dumps(SMALL_TASK),
}


def _recording_evaluator(log: list[tuple[str, int]], name: str) -> Any:
    """Swimmer episodes (the task's own), each logged as (worker name, candidate id)."""
    problem = make_problem("swimmer", **SMALL_TASK)

    def evaluate(config, cid, native):
        log.append((name, cid))
        return problem.evaluate_native(native, seed=episode_seed(config.seed, cid))

    return evaluate


def _run(
    ros: Harness,
    bag: Path,
    workers: int,
    log: list[tuple[str, int]],
    *,
    kill: str | None = None,
    leave: bool = False,
    **settings: Any,
) -> tuple[OptimizerNode, dict[str, SimNode]]:
    """Recorder, oracle, ``workers`` sim nodes and the optimizer on one context, until the
    run ends. ``kill``: the worker destroyed as soon as it holds an assignment it has not
    started (its heartbeats stop; its candidate must be taken over); with ``leave`` it stops
    cleanly instead (``close``: it reports ``stopped``)."""
    writer = BagWriter(bag)
    try:
        recorder = ros.add(RecorderNode(context=ros.ctx, writer=writer))
        sims = {}
        for i in range(workers):
            name = f"sim_{i}"
            sims[name] = ros.add(
                SimNode(
                    context=ros.ctx,
                    cli_args=["--ros-args", "-r", f"__node:={name}"],
                    evaluator=_recording_evaluator(log, name),
                )
            )
        ros.add(OracleNode(context=ros.ctx))
        assert ros.spin_until(
            lambda: recorder.matched([EPISODE_RESULT.name, DUEL_OUTCOME.name]), 10
        )
        opt = ros.add(
            OptimizerNode(
                context=ros.ctx,
                overrides={
                    **SETTINGS,
                    "min_subscribers": 2,
                    "min_workers": workers,
                    "worker_timeout_s": 3.0,
                    "republish_period_s": 0.5,
                    **settings,
                },
            )
        )
        victim = sims.get(kill) if kill else None
        stall = time.monotonic() + 120.0  # a guard against a hang, not a timing assertion
        while not opt.finished:
            assert time.monotonic() < stall, f"run stalled: {dict(opt.counters)}"
            ros.executor.spin_once(timeout_sec=0.01)
            if victim is not None and victim.worker_id in opt.pool.outstanding().values():
                if leave:  # a clean stop: the node says so on its way out
                    ros.executor.remove_node(victim)
                    ros.nodes.remove(victim)
                    victim.close()
                    ros.spin_for(0.2)
                    victim.destroy_node()
                else:
                    ros.remove(victim)
                victim = None
            assert len(log) < 200, "runaway"
        ros.spin_for(0.3)
        ros.remove(recorder)
    finally:
        writer.close()
    return opt, sims


def test_pool_logic_assigns_frees_and_takes_back() -> None:
    pool = WorkerPool(timeout_s=3.0)
    assert pool.assign([0, 1], now=0.0) == []  # no worker known
    pool.heard("a.1", True, 0.0)
    pool.heard("b.2", True, 0.0)
    pool.heard("c.3", False, 0.0)  # not serving (e.g. failed to build the task)
    got = [(a.candidate_id, a.worker) for a in pool.assign([2, 1, 0], now=0.5)]
    assert got == [(0, "a.1"), (1, "b.2")]
    assert pool.assign([0, 1, 2], now=0.6) == []  # both busy
    pool.result(0, ok=True)
    assert [(a.candidate_id, a.worker) for a in pool.assign([0, 1, 2], 0.7)] == [(2, "a.1")]
    pool.heard("a.1", True, 2.5)
    assert pool.expire(now=3.5)[0].candidate_id == 1  # b silent since 0.0
    assert pool.reassigned == 1 and pool.worker_for(0) == "a.1"
    pool.result(2, ok=False)  # a failed episode waits for the failure policy's retry
    got = [(a.candidate_id, a.worker) for a in pool.assign([1, 2], now=3.6)]
    assert got == [(1, "a.1")] and pool.outstanding() == {1: "a.1"}
    pool.result(1, ok=True)
    assert [a.candidate_id for a in pool.assign([2], 3.7)] == []
    assert [a.candidate_id for a in pool.assign([2], 3.7, retry=True)] == [2]
    assert pool.assigned == 5
    pool.heard("a.1", False, 3.8)  # stopping (or failed): heard, but no longer serving
    assert [a.candidate_id for a in pool.expire(now=3.9)] == [2] and pool.reassigned == 2


def test_candidate_worker_field_round_trip_and_old_format() -> None:
    cand = CandidateMsg("r", 3, (0.5, 1.0))
    assert CandidateMsg.decode(cand.encode()) == cand  # old format: no worker key
    assert "worker" not in cand.encode().layout.dim[0].label
    assigned = cand.assigned_to("sim_node.0a1b2c3d")
    assert CandidateMsg.decode(assigned.encode()) == assigned
    bad = cand.encode()
    bad.layout.dim[0].label += ";worker=bad id"
    assert isinstance(CandidateMsg.decode(bad), DecodeError)


def test_two_workers_evaluate_each_candidate_once(ros: Harness, tmp_path: Path) -> None:
    log: list[tuple[str, int]] = []
    opt, sims = _run(ros, tmp_path / "two.mcap", 2, log)
    assert opt.state == "done" and opt.driver.session.evaluations == 18
    per_candidate = Counter(cid for _, cid in log)
    assert sorted(per_candidate) == list(range(18)) and set(per_candidate.values()) == {1}
    per_worker = Counter(name for name, _ in log)
    assert set(per_worker) == {"sim_0", "sim_1"}  # both took part
    assert opt.counters["assigned"] == 18 and opt.counters["reassigned"] == 0
    assert sum(s.counters["candidates_for_others"] for s in sims.values()) > 0
    assert verify(tmp_path / "two.mcap").ok


def test_killed_worker_candidate_taken_over(ros: Harness, tmp_path: Path) -> None:
    log: list[tuple[str, int]] = []
    opt, _ = _run(ros, tmp_path / "kill.mcap", 2, log, kill="sim_1")
    assert opt.state == "done" and opt.driver.session.evaluations == 18
    assert opt.counters["reassigned"] >= 1
    assert sorted(set(cid for _, cid in log)) == list(range(18))
    assert verify(tmp_path / "kill.mcap").ok


def test_two_workers_same_run_as_one(ros: Harness, tmp_path: Path) -> None:
    one_log: list[tuple[str, int]] = []
    two_log: list[tuple[str, int]] = []
    one, _ = _run(ros, tmp_path / "one.mcap", 1, one_log)
    for node in list(ros.nodes):
        if node is not ros.probe:
            ros.remove(node)
    two, _ = _run(ros, tmp_path / "two.mcap", 2, two_log)
    a, b = load_run(tmp_path / "one.mcap"), load_run(tmp_path / "two.mcap")
    assert {k: c.theta for k, c in a.candidates.items()} == {
        k: c.theta for k, c in b.candidates.items()
    }
    assert {o.duel_id: o for o in a.outcomes} == {o.duel_id: o for o in b.outcomes}
    assert len({o.duel_id for o in a.outcomes}) == 17
    assert one.summary().incumbent_theta == two.summary().incumbent_theta
    assert {n for n, _ in one_log} == {"sim_0"} and {n for n, _ in two_log} == {"sim_0", "sim_1"}


def test_worker_leaving_cleanly_hands_over_at_once(ros: Harness, tmp_path: Path) -> None:
    log: list[tuple[str, int]] = []
    # a silent worker would hold its candidate for 10 minutes: only the stop report helps
    opt, _ = _run(
        ros, tmp_path / "leave.mcap", 2, log, kill="sim_1", leave=True, worker_timeout_s=600.0
    )
    assert opt.state == "done" and opt.counters["reassigned"] >= 1
    assert sorted(set(cid for _, cid in log)) == list(range(18))
    assert verify(tmp_path / "leave.mcap").ok


def test_pool_depth_spreads_then_queues() -> None:
    pool = WorkerPool(timeout_s=3.0, depth=2)
    pool.heard("a.1", True, 0.0)
    pool.heard("b.2", True, 0.0)
    got = [(a.candidate_id, a.worker) for a in pool.assign(range(6), now=0.1)]
    assert got == [(0, "a.1"), (1, "b.2"), (2, "a.1"), (3, "b.2")]
    pool.result(1, ok=True)
    assert [(a.candidate_id, a.worker) for a in pool.assign(range(6), 0.2)] == [(4, "b.2")]
