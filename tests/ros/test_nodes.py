"""Each node alone against scripted peers (a probe node), including hostile input."""

from __future__ import annotations

import numpy as np
from diagnostic_msgs.msg import DiagnosticStatus, KeyValue
from localpbo_ros.optimizer_node import OptimizerNode
from localpbo_ros.oracle_node import OracleNode
from localpbo_ros.sim_node import SimNode
from std_msgs.msg import Float64MultiArray, MultiArrayDimension

from localpbo_core.optimizers import Outcome, make_optimizer
from localpbo_core.problems import PreferenceOracle, make_problem
from localpbo_core.seeds import duel_seed, episode_seed
from localpbo_msgs_py import (
    CandidateMsg,
    DuelOutcome,
    DuelRequest,
    EpisodeResult,
    EpisodeStatus,
    OutcomeKind,
    Status,
)
from localpbo_msgs_py.topics import (
    CANDIDATE,
    DUEL_OUTCOME,
    DUEL_REQUEST,
    EPISODE_RESULT,
    INCUMBENT,
    RUN_CONFIG,
    STATUS,
)

from .configs import run_config
from .conftest import SMALL_TASK

OPT = {
    "algorithm": "sobol",
    "task": "swimmer",
    "budget": 8,
    "seed": 4,
    "run_id": "t1",
    "task_options": '{"episode_steps": 50, "value_range": 50.0}',
}


def cfg():
    return run_config(
        run_id="t1",
        algorithm="sobol",
        task="swimmer",
        seed=4,
        budget=8,
        task_options=SMALL_TASK,
        optimizer_options={"initial_design": 2},
    )


def raw_candidate(label: str, data) -> Float64MultiArray:
    """A Float64MultiArray built by hand (the encoder refuses bad values)."""
    msg = Float64MultiArray()
    msg.layout.dim = [MultiArrayDimension(label=label, size=len(data), stride=len(data))]
    msg.data = [float(v) for v in data]
    return msg


def decode_all(cls, msgs):
    return [cls.decode(m) for m in msgs]


# ---------------------------------------------------------------------- simulator
def test_sim_node_evaluates_by_id_and_drops_bad_input(ros) -> None:
    config = cfg()
    calls = []
    problem = make_problem("swimmer", **SMALL_TASK)

    def evaluator(c, cid, native):
        calls.append(cid)
        if cid == 3:
            raise RuntimeError("simulator exploded")
        return problem.evaluate_native(native, seed=episode_seed(c.seed, cid))

    sim = ros.add(SimNode(context=ros.ctx, evaluator=evaluator))
    results = ros.collect(EPISODE_RESULT)
    rng = np.random.default_rng(0)
    thetas = {cid: rng.random(16) for cid in range(4)}
    native = {cid: tuple(problem.to_native(t)) for cid, t in thetas.items()}
    # a candidate before the run config is held, then served
    ros.publish(CANDIDATE, CandidateMsg("t1", 0, native[0]).encode())
    ros.spin_for(0.1)
    ros.publish(RUN_CONFIG, config.encode())
    for cid in (1, 2, 3, 1):  # 1 twice: no second episode
        ros.publish(CANDIDATE, CandidateMsg("t1", cid, native[cid]).encode())
    assert ros.spin_until(lambda: len(results) >= 5, 10)
    got = {}
    for r in decode_all(EpisodeResult, results):
        got.setdefault(r.candidate_id, r)
    for cid in range(3):
        ref = problem.evaluate(thetas[cid], seed=episode_seed(4, cid))
        assert got[cid].status is EpisodeStatus.OK
        assert got[cid].episode_return == ref  # θ evaluated exactly as the optimizer proposed
    assert got[3].status is EpisodeStatus.FAILED and "exploded" in got[3].error
    assert sorted(calls) == [0, 1, 2, 3]
    # hostile candidates: wrong run, wrong length, NaN, out of box, huge, bad label
    n_before = len(results)
    label = "kind=candidate;run=t1;candidate=5"
    hostile = [
        CandidateMsg("other", 5, native[0]).encode(),
        raw_candidate(label, native[0][:3]),
        raw_candidate(label, (float("nan"),) * 16),
        raw_candidate(label, (7.0,) * 16),
        CandidateMsg("t1", 1, tuple(v * 0.5 for v in native[1])).encode(),  # id reuse
        raw_candidate(label, (0.0,) * 100_000),
        raw_candidate("kind=candidate;run=t1", native[0]),
    ]
    for msg in hostile:
        ros.publish(CANDIDATE, msg)
    assert ros.spin_until(
        lambda: sum(v for k, v in sim.counters.items() if k.startswith("dropped_")) == 7, 10
    )
    dropped = {k: v for k, v in sim.counters.items() if k.startswith("dropped_")}
    assert dropped == {  # counted by the decoder's reason, one each
        "dropped_wrong_run": 1,
        "dropped_wrong_shape": 1,
        "dropped_non_finite": 1,
        "dropped_out_of_bounds": 1,
        "dropped_conflicting_candidate": 1,
        "dropped_too_large": 1,
        "dropped_malformed": 1,
    }
    ros.spin_for(0.2)
    assert len(results) == n_before and sorted(calls) == [0, 1, 2, 3]


# ---------------------------------------------------------------------- oracle
def test_oracle_node_matches_by_id_and_uses_reference_oracle(ros) -> None:
    config = cfg()
    oracle = ros.add(OracleNode(context=ros.ctx))
    outs = ros.collect(DUEL_OUTCOME)
    ros.publish(RUN_CONFIG, config.encode())
    values = {0: 1.5, 1: 2.0, 2: -3.0, 3: 0.25}
    # requests before results: they wait
    reqs = [DuelRequest("t1", 0, 1, 0), DuelRequest("t1", 1, 2, 1), DuelRequest("t1", 2, 3, 1)]
    for r in reqs:
        ros.publish(DUEL_REQUEST, r.encode())
    ros.spin_for(0.2)
    assert outs == []
    for cid in (3, 2, 1, 0):  # results out of order
        ros.publish(EPISODE_RESULT, EpisodeResult.ok("t1", cid, values[cid]).encode())
    assert ros.spin_until(lambda: len(outs) >= 3, 10)
    problem = make_problem("swimmer", **SMALL_TASK)
    decoded = {o.duel_id: o for o in decode_all(DuelOutcome, outs)}
    for r in reqs:
        ref = PreferenceOracle(problem, 0.1, seed=duel_seed(4, r.duel_id))  # one duel
        first_wins = ref.compare(values[r.first_id], values[r.second_id])
        assert decoded[r.duel_id].winner_id == (r.first_id if first_wins else r.second_id)
    # repeated request: same answer again; conflicting request and result: dropped
    ros.publish(DUEL_REQUEST, reqs[0].encode())
    ros.publish(DUEL_REQUEST, DuelRequest("t1", 0, 2, 3).encode())
    ros.publish(EPISODE_RESULT, EpisodeResult.ok("t1", 0, 9.0).encode())
    ros.publish(EPISODE_RESULT, EpisodeResult.ok("other", 0, 9.0).encode())
    bad = DiagnosticStatus(
        name="localpbo/duel_request", values=[KeyValue(key="run_id", value="t1")]
    )
    ros.publish(DUEL_REQUEST, bad)
    assert ros.spin_until(lambda: len(outs) >= 4 and oracle.counters["dropped_malformed"] == 1, 10)
    assert DuelOutcome.decode(outs[3]) == decoded[0]
    assert oracle.counters["dropped_conflicting_request"] == 1
    assert oracle.counters["dropped_conflicting_result"] == 1
    assert oracle.counters["dropped_wrong_run"] == 1
    # a failed episode fails its duel
    ros.publish(DUEL_REQUEST, DuelRequest("t1", 3, 4, 0).encode())
    ros.publish(EPISODE_RESULT, EpisodeResult.failed("t1", 4, "boom").encode())
    assert ros.spin_until(lambda: len(outs) >= 5, 10)
    last = DuelOutcome.decode(outs[4])
    assert last.kind is OutcomeKind.FAILED and "boom" in last.reason


# ---------------------------------------------------------------------- optimizer
def _scripted_peer(ros, answer):
    """Answer duel requests with ``answer(request, candidates)`` (an outcome, or None to stay
    silent) once both candidates are known; each duel id is answered at most once per
    request message."""
    cands: dict[int, CandidateMsg] = {}
    waiting: list[DuelRequest] = []
    ros.publisher(DUEL_OUTCOME)

    def flush():
        for r in list(waiting):
            if r.first_id in cands and r.second_id in cands:
                waiting.remove(r)
                outcome = answer(r, cands)
                if outcome is not None:
                    ros.publish(DUEL_OUTCOME, outcome.encode())

    def on_candidate(msg):
        c = CandidateMsg.decode(msg)
        cands[c.candidate_id] = c
        flush()

    def on_request(msg):
        waiting.append(DuelRequest.decode(msg))
        flush()

    ros.probe.create_subscription(CANDIDATE.msg_type, CANDIDATE.name, on_candidate, CANDIDATE.qos)
    ros.probe.create_subscription(
        DUEL_REQUEST.msg_type, DUEL_REQUEST.name, on_request, DUEL_REQUEST.qos
    )
    return cands


def test_optimizer_node_against_scripted_oracle_and_hostile_outcomes(ros) -> None:
    problem = make_problem("swimmer", **SMALL_TASK)
    held: list[DuelRequest] = []

    def judge(r, cands):
        a, b = cands[r.first_id].theta, cands[r.second_id].theta
        return DuelOutcome.decisive(r, r.first_id if a[0] > b[0] else r.second_id)

    def answer(r, cands):
        if r.duel_id == 3 and not held:
            held.append(r)
            return None
        return judge(r, cands)

    opt = ros.add(OptimizerNode(context=ros.ctx, overrides={**OPT, "republish_period_s": 60.0}))
    incumbents = ros.collect(INCUMBENT)
    cands = _scripted_peer(ros, answer)
    assert ros.spin_until(lambda: bool(held), 20)
    history = opt.driver.session.optimizer.history
    r = held[0]
    good = judge(r, cands)
    for msg in hostile_messages(r, good.winner_id, opt.driver.accepted):
        ros.publish(DUEL_OUTCOME, msg)
    assert ros.spin_until(
        lambda: (
            sum(v for k, v in opt.counters.items() if k.startswith("dropped_")) == 6
            and opt.counters["outcomes_duplicate"] == 1
        ),
        10,
    )
    assert opt.driver.session.optimizer.history == history  # state unchanged by bad input
    assert opt.driver.pending_requests() == (r,)
    ros.publish(DUEL_OUTCOME, good.encode())
    assert ros.spin_until(lambda: opt.finished, 20)
    assert opt.state == "done" and opt.driver.n_duels == 7
    # independent reference: the optimizer driven directly with the same judge
    ref = make_optimizer("sobol", 16, seed=4, budget=8, initial_design=2)
    while not ref.done:
        ask = ref.ask()
        outs = []
        for d in ask.duels:
            a = ref.history.candidates[d.first].theta
            b = ref.history.candidates[d.second].theta
            outs.append(Outcome(d.first, d.second) if a[0] > b[0] else Outcome(d.second, d.first))
        ref.tell(outs)
    for c in ref.history.candidates:
        assert cands[c.id].theta == tuple(problem.to_native(c.theta))
    assert ros.spin_until(lambda: bool(incumbents) and _last_inc(incumbents).n_duels == 7, 5)
    assert _last_inc(incumbents).candidate_id == ref.incumbent.id
    c = opt.counters
    assert c["dropped_wrong_run"] == 1 and c["dropped_malformed"] == 2
    assert c["dropped_unknown_duel"] == 1 and c["dropped_mismatched_duel"] == 1
    assert c["dropped_repeated"] == 1
    # the counters travel on the status topic
    statuses = ros.collect(STATUS)
    ros.spin_for(0.2)
    opt.publish_status()
    assert ros.spin_until(
        lambda: any(Status.decode(m).node == "optimizer_node" for m in statuses), 5
    )
    reported = [Status.decode(m) for m in statuses if Status.decode(m).node == "optimizer_node"][-1]
    assert reported.state == "done" and reported.run_id == "t1"
    assert reported.counters["dropped_wrong_run"] == 1
    assert reported.counters["dropped_repeated"] == 1 and reported.counters["duels_done"] == 7


def _last_inc(msgs):
    from localpbo_msgs_py import Incumbent

    return Incumbent.decode(msgs[-1])


def hostile_messages(r: DuelRequest, winner: int, accepted: list[DuelOutcome]) -> list[object]:
    """Wrong run, malformed (2), unknown duel, mismatched ids, repeated earlier duel (with
    another winner), and an exact duplicate of an accepted outcome."""
    wrong_run = DuelOutcome.decisive(
        DuelRequest("other", r.duel_id, r.first_id, r.second_id), winner
    ).encode()
    no_kind = DuelOutcome.decisive(r, winner).encode()
    no_kind.values = [kv for kv in no_kind.values if kv.key != "kind"]
    nan_id = DuelOutcome.decisive(r, winner).encode()
    for kv in nan_id.values:
        if kv.key == "winner_id":
            kv.value = "nan"
    unknown = DuelOutcome.decisive(DuelRequest("t1", 999, r.first_id, r.second_id), winner).encode()
    other = (r.first_id + 1) if (r.first_id + 1) != r.second_id else r.first_id + 2
    mismatched = DuelOutcome.decisive(
        DuelRequest("t1", r.duel_id, other, r.second_id), other
    ).encode()
    first = accepted[0]  # duel 0, answered: a different answer is a repeated outcome
    repeated = DuelOutcome.decisive(
        DuelRequest("t1", 0, first.first_id, first.second_id), first.loser_id
    ).encode()
    duplicate = first.encode()  # an exact copy is benign (counted, not dropped)
    return [wrong_run, no_kind, nan_id, unknown, mismatched, repeated, duplicate]


def test_optimizer_failure_policies(ros) -> None:
    # a peer that fails duel 2 twice and then answers: retry policy carries on
    fails: dict[int, int] = {}

    def flaky(r, cands):
        if r.duel_id == 2 and fails.get(2, 0) < 2:
            fails[2] = fails.get(2, 0) + 1
            return DuelOutcome.failed(r, "episode failed")
        return DuelOutcome.decisive(r, r.first_id)

    opt = ros.add(OptimizerNode(context=ros.ctx, overrides={**OPT, "max_retries": 2}))
    _scripted_peer(ros, flaky)
    assert ros.spin_until(lambda: opt.finished, 20)
    assert opt.state == "done" and opt.counters["retries"] == 2
    assert opt.counters["failed_duels"] == 2


def test_optimizer_stop_policy(ros) -> None:

    def failing(r, cands):
        return (
            DuelOutcome.failed(r, "simulator raised")
            if r.duel_id == 1
            else (DuelOutcome.decisive(r, r.first_id))
        )

    stop = ros.add(OptimizerNode(context=ros.ctx, overrides={**OPT, "failure_policy": "stop"}))
    _scripted_peer(ros, failing)
    assert ros.spin_until(lambda: stop.finished, 20)
    assert stop.state == "failed" and "simulator raised" in stop.error
    assert stop.driver.n_duels == 1


def test_optimizer_silent_peer_times_out(ros) -> None:
    opt = ros.add(
        OptimizerNode(context=ros.ctx, overrides={**OPT, "duel_timeout_s": 0.3, "max_retries": 1})
    )
    requests = []
    ros.probe.create_subscription(
        DUEL_REQUEST.msg_type, DUEL_REQUEST.name, requests.append, DUEL_REQUEST.qos
    )
    ros.probe.create_subscription(CANDIDATE.msg_type, CANDIDATE.name, lambda m: None, CANDIDATE.qos)
    assert ros.spin_until(lambda: opt.finished, 10)
    assert opt.state == "failed" and "timeout" in opt.error
    assert opt.counters["retries"] == 1 and len(requests) >= 2
    assert opt.driver.n_duels == 0


def test_followers_switch_to_a_new_run_or_stick_to_their_run_id(ros) -> None:
    config_a = cfg()
    config_b = run_config(
        run_id="t2", algorithm="sobol", task="swimmer", seed=9, budget=8, task_options=SMALL_TASK
    )
    free = ros.add(SimNode(context=ros.ctx, evaluator=lambda c, cid, th: float(c.seed)))
    pinned = ros.add(OracleNode(context=ros.ctx, overrides={"run_id": "t1"}))
    results = ros.collect(EPISODE_RESULT)
    ros.publish(RUN_CONFIG, config_a.encode())
    assert ros.spin_until(lambda: free.run_id == "t1" and pinned.run_id == "t1", 5)
    conflicting = run_config(
        run_id="t1", algorithm="sobol", task="swimmer", seed=5, budget=8, task_options=SMALL_TASK
    )
    ros.publish(RUN_CONFIG, conflicting.encode())
    assert ros.spin_until(lambda: free.counters["dropped_conflicting_config"] == 1, 5)
    ros.publish(RUN_CONFIG, config_b.encode())
    assert ros.spin_until(
        lambda: free.run_id == "t2" and pinned.counters["dropped_wrong_run"] == 1, 5
    )
    assert pinned.run_id == "t1"
    theta = tuple(config_b.lower)
    ros.publish(CANDIDATE, CandidateMsg("t2", 0, theta).encode())
    assert ros.spin_until(lambda: len(results) == 1, 5)
    res = EpisodeResult.decode(results[0])
    assert res.run_id == "t2" and res.episode_return == 9.0
