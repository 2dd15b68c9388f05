"""The full three-node loop over topics, recorded, read back independently and verified."""

from __future__ import annotations

import json
import time
from collections import Counter

from localpbo_ros.bagtools import load_run
from localpbo_ros.optimizer_node import OptimizerNode
from localpbo_ros.oracle_node import OracleNode
from localpbo_ros.recorder_node import RecorderNode
from localpbo_ros.replay import play, qos_from_metadata, verify
from localpbo_ros.sim_node import SimNode
from localpbo_ros.suite import run_suite
from mcap_ros2.reader import read_ros2_messages
from rosbags.highlevel import AnyReader

from localpbo_core.optimizers import Outcome, make_optimizer
from localpbo_msgs_py import DuelOutcome, EpisodeResult, OutcomeKind
from localpbo_msgs_py.bag import read_messages
from localpbo_msgs_py.qos_yaml import offered_qos_yaml
from localpbo_msgs_py.topics import (
    ALL_TOPICS,
    CANDIDATE,
    DUEL_OUTCOME,
    EPISODE_RESULT,
    RUN_CONFIG,
)

from .conftest import SMALL_TASK

SETTINGS = {
    "algorithm": "sobol",
    "task": "swimmer",
    "budget": 30,
    "seed": 11,
    "run_id": "loop",
    "task_options": json.dumps(SMALL_TASK),
}


def test_full_loop_recorded_and_verified(tmp_path) -> None:
    bag = tmp_path / "loop.mcap"
    summary = run_suite(SETTINGS, bag, timeout_s=60)
    assert summary.state == "done" and summary.duels == 29 and summary.evaluations == 30
    # independent reader 1: mcap_ros2 (decodes from the embedded ros2msg schemas)
    msgs = list(read_ros2_messages(str(bag)))
    per_topic = Counter(m.channel.topic for m in msgs)
    assert set(per_topic) <= {t.name for t in ALL_TOPICS}
    assert per_topic[RUN_CONFIG.name] >= 1 and per_topic[CANDIDATE.name] >= 30
    decisive = [
        DuelOutcome.decode(_to_rclpy(m.ros_msg))
        for m in msgs
        if m.channel.topic == DUEL_OUTCOME.name
    ]
    ids = Counter(o.duel_id for o in decisive if o.kind is OutcomeKind.DECISIVE)
    assert sorted(ids) == list(range(29)) and set(ids.values()) == {1}
    # the summary's episode returns are the recorded ones of the best and the first candidate
    returns = {
        r.candidate_id: r.episode_return
        for r in (
            EpisodeResult.decode(_to_rclpy(m.ros_msg))
            for m in msgs
            if m.channel.topic == EPISODE_RESULT.name
        )
    }
    assert summary.incumbent_return == returns[summary.incumbent_id]
    assert summary.first_candidate_return == returns[0]
    assert summary.recommended_return == returns[summary.recommended_id]
    text = summary.format()
    assert (
        f"recommended candidate (highest posterior mean utility given all duels): id "
        f"{summary.recommended_id}," in text
    )
    assert f"recommended {returns[summary.recommended_id]:.1f}" in text
    cfg = json.loads(next(m.ros_msg.data for m in msgs if m.channel.topic == RUN_CONFIG.name))
    assert cfg["run_id"] == "loop" and cfg["seed"] == 11 and cfg["budget"] == 30
    # independent reader 2: rosbags
    with AnyReader([bag]) as reader:
        counts = Counter(conn.topic for conn, _, _ in reader.messages())
        qos = {c.topic: c.ext.offered_qos_profiles for c in reader.connections}
    assert counts == per_topic
    assert qos[RUN_CONFIG.name][0].durability.name == "TRANSIENT_LOCAL"
    assert qos[DUEL_OUTCOME.name][0].durability.name == "VOLATILE"
    # the recorded outcomes drive a fresh optimizer to the recorded candidates
    report = verify(bag)
    assert report.ok, report.format()
    assert report.candidates_checked == 30 and report.outcomes_used == 29
    # and an optimizer told the same outcomes directly ends with the same incumbent
    run = load_run(bag)
    ref = make_optimizer("sobol", 16, seed=11, budget=30, initial_design=2)
    outs = {o.duel_id: o for o in run.outcomes}
    did = 0
    while not ref.done:
        ask = ref.ask()
        ref.tell(
            [
                Outcome(outs[did + i].winner_id, outs[did + i].loser_id)
                for i in range(len(ask.duels))
            ]
        )
        did += len(ask.duels)
    assert summary.incumbent_id == ref.incumbent.id


def _to_rclpy(msg):
    """mcap_ros2's dynamic message -> the rclpy DiagnosticStatus the codec expects."""
    from diagnostic_msgs.msg import DiagnosticStatus, KeyValue

    return DiagnosticStatus(
        level=bytes([msg.level]),
        name=msg.name,
        message=msg.message,
        hardware_id=msg.hardware_id,
        values=[KeyValue(key=kv.key, value=kv.value) for kv in msg.values],
    )


def test_verify_detects_tampering(tmp_path) -> None:
    from localpbo_msgs_py.bag import BagWriter, read_messages

    bag = tmp_path / "a.mcap"
    run_suite({**SETTINGS, "budget": 8}, bag, timeout_s=60)
    tampered = tmp_path / "b.mcap"
    with BagWriter(tampered) as w:
        w.add_suite_topics()
        for rec in read_messages(bag):
            msg = rec.message
            if rec.topic == CANDIDATE.name and "candidate=5" in msg.layout.dim[0].label:
                msg.data = [msg.data[0] * 0.5, *msg.data[1:]]
            w.write(rec.topic, msg, log_time_ns=rec.log_time_ns)
    report = verify(tampered)
    assert not report.ok and "candidate 5" in report.mismatch


def test_late_joining_simulator(ros) -> None:
    opt = ros.add(
        OptimizerNode(
            context=ros.ctx,
            overrides={**SETTINGS, "budget": 6, "republish_period_s": 0.2, "min_subscribers": 0},
        )
    )
    ros.add(OracleNode(context=ros.ctx))
    ros.spin_for(0.5)  # work published with nobody to evaluate it
    assert opt.driver.n_duels == 0 and opt.driver.step_open
    sim = ros.add(SimNode(context=ros.ctx))
    assert ros.spin_until(lambda: opt.finished, 30)
    assert opt.state == "done" and opt.driver.n_duels == 5
    assert sim.counters["episodes"] == 6


def test_late_joining_oracle_gets_earlier_results(ros) -> None:
    opt = ros.add(
        OptimizerNode(
            context=ros.ctx,
            overrides={**SETTINGS, "budget": 6, "republish_period_s": 0.2, "min_subscribers": 0},
        )
    )
    sim = ros.add(SimNode(context=ros.ctx))
    assert ros.spin_until(lambda: sim.counters["episodes"] == 2, 10)  # evaluated, unheard
    ros.spin_for(0.3)
    assert opt.driver.n_duels == 0
    ros.add(OracleNode(context=ros.ctx))
    assert ros.spin_until(lambda: opt.finished, 30)
    assert opt.state == "done" and opt.driver.n_duels == 5
    assert sim.counters["episodes"] == 6  # re-published results, no episode run twice
    assert sim.counters["results_repeated"] >= 2


def test_play_republishes_with_timing_and_qos(ros, tmp_path) -> None:
    bag = tmp_path / "p.mcap"
    run_suite({**SETTINGS, "budget": 6}, bag, timeout_s=60)
    got = ros.collect(DUEL_OUTCOME)
    recorder_path = tmp_path / "again.mcap"
    recorder = ros.add(RecorderNode(context=ros.ctx, overrides={"path": str(recorder_path)}))
    from rclpy.node import Node

    player = ros.add(Node("player", context=ros.ctx, start_parameter_services=False))
    start = time.monotonic()
    sent = play(
        bag, player, ros.executor, rate=4.0, loops=2, topics=[DUEL_OUTCOME.name, RUN_CONFIG.name]
    )
    elapsed = time.monotonic() - start
    ros.spin_for(0.3)
    assert sent == 2 * (5 + 1) and len(got) == 2 * 5
    # original timing divided by the rate: each pass lasts the recorded span / 4
    stamps = [
        r.log_time_ns for r in read_messages(bag, topics=[DUEL_OUTCOME.name, RUN_CONFIG.name])
    ]
    span = (max(stamps) - min(stamps)) / 1e9 / 4.0
    assert elapsed >= 2 * span * 0.9
    assert recorder.recorded >= 6
    # latched topic played transient-local: a late subscriber still gets the run config
    late = ros.collect(RUN_CONFIG)
    assert ros.spin_until(lambda: len(late) == 1, 5)


def test_playback_qos_from_offered_profiles() -> None:
    for spec in ALL_TOPICS:
        qos = qos_from_metadata(offered_qos_yaml([spec.qos]))
        assert (qos.reliability, qos.durability, qos.depth) == (
            spec.qos.reliability,
            spec.qos.durability,
            spec.qos.depth,
        )
    default = qos_from_metadata("")
    assert default.durability.name == "VOLATILE" and default.depth == 10


def _flaky_evaluator(fail_times: int):
    """Swimmer episodes, except candidate 3 raises ``fail_times`` times first."""
    from localpbo_core.problems import make_problem
    from localpbo_core.seeds import episode_seed

    problem = make_problem("swimmer", **SMALL_TASK)
    failures = Counter()

    def evaluate(config, cid, native):
        if cid == 3 and failures[cid] < fail_times:
            failures[cid] += 1
            raise RuntimeError("physics blew up")
        return problem.evaluate_native(native, seed=episode_seed(config.seed, cid))

    return evaluate, failures


def test_failing_simulator_retry_then_complete(tmp_path) -> None:
    evaluate, failures = _flaky_evaluator(2)
    summary = run_suite(
        {**SETTINGS, "budget": 8, "max_retries": 2},
        tmp_path / "r.mcap",
        evaluator=evaluate,
        timeout_s=60,
    )
    assert summary.state == "done" and summary.duels == 7 and failures[3] == 2
    # the failed duel outcomes are in the bag, and the run still verifies
    kinds = Counter(o.kind for o in load_run(tmp_path / "r.mcap").outcomes)
    assert kinds[OutcomeKind.FAILED] == 2 and kinds[OutcomeKind.DECISIVE] == 7
    assert verify(tmp_path / "r.mcap").ok
    # same outcomes as a run whose simulator never failed
    clean = run_suite({**SETTINGS, "budget": 8}, tmp_path / "c.mcap", timeout_s=60)
    assert clean.incumbent_id == summary.incumbent_id
    assert clean.incumbent_theta == summary.incumbent_theta


def test_failing_simulator_stop_policy(tmp_path) -> None:
    evaluate, _ = _flaky_evaluator(1)
    summary = run_suite(
        {**SETTINGS, "budget": 8, "failure_policy": "stop"},
        tmp_path / "s.mcap",
        evaluator=evaluate,
        timeout_s=60,
    )
    assert summary.state == "failed" and "physics blew up" in summary.error
    assert summary.duels == 2  # duels 0 and 1 done; duel 2 (candidate 3) failed
