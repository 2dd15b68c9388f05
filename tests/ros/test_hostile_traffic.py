"""Hostile peers: floods of malformed, oversized and forged well-formed messages. Counters exact,
log lines, node state and bag size bounded, no episode for a forged candidate."""

from __future__ import annotations

import time
from dataclasses import replace
from typing import Any

import pytest
from diagnostic_msgs.msg import DiagnosticStatus, KeyValue
from localpbo_ros.admission import IdRange, id_range
from localpbo_ros.evaluator import EvaluatorNode
from localpbo_ros.oracle_node import OracleNode
from localpbo_ros.recorder_node import PARAMS as RECORDER_PARAMS
from localpbo_ros.recorder_node import RecorderNode
from localpbo_ros.sim_node import SimNode
from rclpy.serialization import serialize_message
from std_msgs.msg import Float64MultiArray, MultiArrayDimension

from localpbo_core.provenance import recording_platform
from localpbo_core.validation import SettingError
from localpbo_msgs_py import CandidateMsg, DuelRequest, EpisodeResult, Incumbent, RunConfig, Status
from localpbo_msgs_py._validate import MAX_ID, MAX_KEYVALUES, MAX_TEXT, MAX_THETA_LEN
from localpbo_msgs_py.bag import read_messages, summarize
from localpbo_msgs_py.limits import MAX_MESSAGE_BYTES, max_message_bytes
from localpbo_msgs_py.run_config import MAX_CONFIG_BYTES
from localpbo_msgs_py.topics import (
    ALL_TOPICS,
    CANDIDATE,
    DUEL_REQUEST,
    EPISODE_RESULT,
    RUN_CONFIG,
    STATUS,
    TopicSpec,
)

from .configs import run_config
from .conftest import SMALL_TASK

RECORDER_DEFAULTS = {p.name: p.default for p in RECORDER_PARAMS}


class FrozenClock:
    """A monotonic clock the test moves by hand (the warning throttle reads it)."""

    def __init__(self) -> None:
        self.now = 1000.0

    def __call__(self) -> float:
        return self.now


def dropped(node: Any) -> int:
    return sum(v for k, v in node.counters.items() if k.startswith("dropped_"))


def flood(ros: Any, node: Any, sends: list[tuple[Any, Any]], total: Any) -> None:
    """Publish in batches of 20 and let ``node`` take each batch (no history overflows)."""
    for start in range(0, len(sends), 20):
        batch = sends[start : start + 20]
        target = total(node) + len(batch)
        for spec, msg in batch:
            ros.publish(spec, msg)
        assert ros.spin_until(lambda t=target: total(node) == t, 20)


def settle(ros: Any, progress: Any, quiet_s: float = 0.2, timeout: float = 20.0) -> None:
    """Spin until ``progress()`` has not changed for ``quiet_s`` seconds."""
    end = time.monotonic() + timeout
    last, since = progress(), time.monotonic()
    while time.monotonic() < end and time.monotonic() - since < quiet_s:
        ros.spin_for(0.02)
        now = progress()
        if now != last:
            last, since = now, time.monotonic()


def warning_lines(text: str, marker: str) -> list[str]:
    return [line for line in text.splitlines() if marker in line]


def oversized_request() -> DiagnosticStatus:
    values = [KeyValue(key=f"k{i}", value="v") for i in range(65)]
    return DiagnosticStatus(name="localpbo/duel_request", values=values)


def test_oracle_flood_counts_exactly_and_logs_once_per_reason(ros: Any, capfd: Any) -> None:
    oracle = ros.add(OracleNode(context=ros.ctx))
    clock = FrozenClock()
    oracle.warnings.clock = clock
    config = run_config(
        run_id="t1", algorithm="sobol", task="swimmer", seed=4, budget=8, task_options=SMALL_TASK
    )
    ros.publish(RUN_CONFIG, config.encode())
    assert ros.spin_until(lambda: oracle.run_id == "t1", 5)
    nan_result = EpisodeResult.ok("t1", 1, 1.0).encode()
    for kv in nan_result.values:
        if kv.key == "episode_return":
            kv.value = "nan"
    kinds = {
        "wrong_run": (DUEL_REQUEST, DuelRequest("other", 0, 1, 2).encode()),
        "malformed": (DUEL_REQUEST, DiagnosticStatus(name="localpbo/duel_request")),
        "too_large": (DUEL_REQUEST, oversized_request()),
        "non_finite": (EPISODE_RESULT, nan_result),
    }
    n_each = 60
    sends = [kinds[k] for _ in range(n_each) for k in kinds]
    capfd.readouterr()
    flood(ros, oracle, sends, dropped)
    expected = {f"dropped_{k}": n_each for k in kinds}
    assert {k: v for k, v in oracle.counters.items() if k.startswith("dropped_")} == expected
    lines = warning_lines(capfd.readouterr().err, "dropped message (")
    assert len(lines) == len(kinds), lines  # one per reason, the rest held back
    # after the throttle period the next line says how many were held back
    clock.now += oracle.warnings.period_s
    flood(ros, oracle, [kinds["wrong_run"]], dropped)
    (line,) = warning_lines(capfd.readouterr().err, "dropped message (")
    assert "(wrong_run)" in line and f"({n_each - 1} similar warnings suppressed" in line
    # the status topic carries the exact counts
    statuses = ros.collect(STATUS)
    ros.spin_for(0.1)
    oracle.publish_status()
    assert ros.spin_until(lambda: bool(statuses), 5)
    status = Status.decode(statuses[-1])
    assert isinstance(status, Status)
    assert status.counters["dropped_wrong_run"] == n_each + 1
    assert status.counters["dropped_too_large"] == n_each


def theta_message(n: int, run: str = "t1", candidate: int = 1) -> Float64MultiArray:
    msg = Float64MultiArray()
    label = f"kind=candidate;run={run};candidate={candidate}"
    msg.layout.dim = [MultiArrayDimension(label=label, size=n, stride=n)]
    msg.data = [0.5] * n
    return msg


def wide_config(dim: int, run_id: str = "t1", budget: int = 50) -> RunConfig:
    """A run config whose θ has ``dim`` coordinates in [0, 1] (the recorder's triage needs
    only its id, box and budget)."""
    return RunConfig(run_id, "sobol", "task", dim, (0.0,) * dim, (1.0,) * dim, 0, budget)


def recorder_handled(node: Any) -> int:
    c = node.counters
    return len(node._held) + sum(
        c[k]
        for k in (
            "recorded",
            "recorded_foreign",
            "dropped_oversized",
            "dropped_bag_full",
            "dropped_foreign_quota",
        )
    )


def start_recorder(ros: Any, path: Any, topics: list[TopicSpec], **overrides: Any) -> Any:
    recorder = ros.add(
        RecorderNode(context=ros.ctx, overrides={"path": str(path), **overrides}, topics=topics)
    )
    recorder.warnings.clock = FrozenClock()
    for spec in topics:
        ros.publisher(spec)
    assert ros.spin_until(lambda: recorder.matched([t.name for t in topics]), 5)
    return recorder


def test_recorder_drops_oversized_and_caps_the_bag(ros: Any, tmp_path: Any, capfd: Any) -> None:
    path = tmp_path / "flood.mcap"
    cap = 200_000
    recorder = start_recorder(
        ros, path, [RUN_CONFIG, CANDIDATE], max_message_bytes=20_000, max_bag_bytes=cap
    )
    ros.publish(RUN_CONFIG, wide_config(1000).encode())
    assert ros.spin_until(lambda: recorder.counters["recorded"] == 1, 5)
    legit = theta_message(1000)  # 8 kB: fits the message limit
    huge = theta_message(10_000)  # 80 kB: above it
    sends = [(CANDIDATE, huge if i % 3 == 0 else legit) for i in range(120)]
    capfd.readouterr()
    flood(ros, recorder, sends, recorder_handled)
    c = recorder.counters
    assert recorder.max_foreign == cap // 2  # foreign traffic gets at most half of a cap
    assert c["dropped_oversized"] == 40
    assert c["recorded"] - 1 + c["dropped_bag_full"] == 80
    assert c["dropped_bag_full"] > 0 and recorder.bag_full
    err = capfd.readouterr().err
    assert len(warning_lines(err, "dropped message (oversized)")) == 1
    assert len(warning_lines(err, "max_bag_bytes")) == 1
    recorder.close()
    summary = summarize(path)
    assert summary.complete
    assert summary.message_count == c["recorded"]
    # the cap holds for the data; closing adds the summary section (indexes, statistics)
    assert path.stat().st_size <= cap + 16 * 1024
    assert all(len(m.message.data) == 1000 for m in read_messages(path, topics=[CANDIDATE.name]))
    # the bag says it is capped, and what was not recorded
    assert summary.recorder["bag_full"] == "yes"
    assert summary.recorder_counts()["dropped_oversized"] == 40
    text = summary.format()
    assert f"capped at {cap} bytes: {c['dropped_bag_full']} messages not recorded" in text
    assert "oversized 40" in text
    # and where it was recorded, written when it opened
    assert summary.platform == recording_platform()
    assert f"code {summary.platform['code.digest']}" in text


def test_a_flood_never_crowds_the_run_out_of_the_bag(ros: Any, tmp_path: Any) -> None:
    """Foreign traffic (another run, ids out of range, malformed, before the config) takes at
    most its share; every message of the run is recorded on its topic, in a capped bag."""
    path = tmp_path / "crowd.mcap"
    cap, share = 400_000, 50_000
    topics = [RUN_CONFIG, CANDIDATE, DUEL_REQUEST]
    recorder = start_recorder(
        ros, path, topics, max_bag_bytes=cap, max_foreign_bytes=share, max_message_bytes=20_000
    )
    early = theta_message(100, candidate=0)  # before the config: held, then the run's
    flood(ros, recorder, [(CANDIDATE, early)], recorder_handled)
    assert len(recorder._held) == 1
    flood(ros, recorder, [(RUN_CONFIG, wide_config(100).encode())], recorder_handled)
    assert recorder.counters["recorded"] == 2 and not recorder._held
    foreign = [
        (CANDIDATE, theta_message(100, run="other")),  # another run
        (CANDIDATE, theta_message(100, candidate=10**7)),  # id out of range
        (DUEL_REQUEST, DuelRequest("t1", 5 * 10**6, 0, 1).encode()),
        (DUEL_REQUEST, oversized_request()),  # malformed: too many keys
    ]
    run = [(CANDIDATE, theta_message(100, candidate=i)) for i in range(40)]
    run += [(DUEL_REQUEST, DuelRequest("t1", i, i, i + 1).encode()) for i in range(39)]
    sends: list[tuple[TopicSpec, Any]] = []
    for i, item in enumerate(run):
        sends.append(item)
        sends.extend(foreign * 3 if i % 2 else [])
    flood(ros, recorder, sends, recorder_handled)
    c = recorder.counters
    assert c["recorded"] == 2 + len(run)
    assert c["dropped_foreign_quota"] > 0 and not recorder.bag_full
    assert recorder.foreign_bytes <= share
    rounds = sum(1 for i in range(len(run)) if i % 2)
    assert c["foreign_wrong_run"] == c["foreign_id_out_of_range"] // 2 == rounds * 3
    assert c["foreign_too_large"] == rounds * 3
    recorder.close()
    # the run's topics hold the run only: every candidate and request, none foreign
    cands = [CandidateMsg.decode(m.message) for m in read_messages(path, topics=[CANDIDATE.name])]
    assert [x.candidate_id for x in cands if isinstance(x, CandidateMsg)] == [0, *range(40)]
    reqs = [DuelRequest.decode(m.message) for m in read_messages(path, topics=[DUEL_REQUEST.name])]
    assert [r.duel_id for r in reqs if isinstance(r, DuelRequest)] == list(range(39))
    summary = summarize(path)
    counts = {t.topic: t.count for t in summary.topics}
    assert (
        counts["/localpbo/foreign/candidate"] + counts["/localpbo/foreign/duel_request"]
        == (c["recorded_foreign"])
    )
    assert summary.recorder["bag_full"] == "no"
    text = summary.format()
    assert f"dropped_foreign_quota {c['dropped_foreign_quota']}" not in text  # reasons shown bare
    assert f"foreign_quota {c['dropped_foreign_quota']}" in text
    assert "wrong_run" in text and "id_out_of_range" in text


WIDE = "\U0001f600"  # 4 bytes in UTF-8: the worst case per character
RUN = "r" * 64


def largest_valid_message(spec: TopicSpec) -> Any:
    """The largest message of ``spec``'s type that its decoder accepts."""
    if spec.type_name == "std_msgs/msg/Float64MultiArray":
        theta = (0.5,) * MAX_THETA_LEN
        msg = Incumbent(RUN, MAX_ID, theta, MAX_ID).encode()
        assert isinstance(Incumbent.decode(msg), Incumbent)
        return msg
    if spec.type_name == "diagnostic_msgs/msg/DiagnosticStatus":
        msg = EpisodeResult.failed(RUN, MAX_ID, WIDE * MAX_TEXT).encode()
        msg.hardware_id = WIDE * MAX_TEXT
        assert isinstance(EpisodeResult.decode(msg), EpisodeResult)
        return msg
    if spec.type_name == "diagnostic_msgs/msg/DiagnosticArray":
        info = {f"{i:02d}".join(("x", "y" * 60)): WIDE * MAX_TEXT for i in range(MAX_KEYVALUES - 3)}
        msg = Status(RUN, "n" * 64, "s" * 64, 3, WIDE * MAX_TEXT, {}, info, 2**62).encode()
        msg.status[0].hardware_id = WIDE * MAX_TEXT
        assert isinstance(Status.decode(msg), Status)
        return msg
    assert spec.type_name == "std_msgs/msg/String"
    base = RunConfig(RUN, "a", "t", 1, (0.0,), (1.0,), 0, 1, {"pad": ""})
    pad = MAX_CONFIG_BYTES - len(base.to_json().encode())
    config = RunConfig(RUN, "a", "t", 1, (0.0,), (1.0,), 0, 1, {"pad": "x" * pad})
    msg = config.encode()
    assert len(msg.data.encode()) == MAX_CONFIG_BYTES
    assert isinstance(RunConfig.decode(msg), RunConfig)
    return msg


@pytest.mark.parametrize("spec", ALL_TOPICS, ids=lambda s: s.key)
def test_message_bounds_cover_the_largest_legitimate_messages(spec: TopicSpec) -> None:
    """The bounds the recorder's default limit (2 x MAX_MESSAGE_BYTES) is made of lie above
    every message a decoder accepts: the largest one of each topic, serialized."""
    size = len(serialize_message(largest_valid_message(spec)))
    assert size <= max_message_bytes(spec) <= MAX_MESSAGE_BYTES
    assert RECORDER_DEFAULTS["max_message_bytes"] == 2 * MAX_MESSAGE_BYTES


# ---------------------------------------------------------------------- forged ids
FORGED_IDS = (16, 17, 100, 3558, 10**7, 10**7 + 1, 2**40, MAX_ID)
"""Well-formed ids outside a budget-8 run (candidate ids 0..15)."""


def cheap_config(run_id: str = "t1", budget: int = 8) -> RunConfig:
    return run_config(run_id=run_id, algorithm="sobol", task="hartmann6", budget=budget)


def test_sim_node_runs_no_episode_for_forged_candidate_ids(ros: Any) -> None:
    calls: list[int] = []

    def evaluator(config: RunConfig, cid: int, theta: Any) -> float:
        calls.append(cid)
        return float(cid)

    sim = ros.add(SimNode(context=ros.ctx, evaluator=evaluator))
    sim.warnings.clock = FrozenClock()
    config = cheap_config()
    ros.publish(RUN_CONFIG, config.encode())
    assert ros.spin_until(lambda: sim.run_id == "t1", 5)
    results = ros.collect(EPISODE_RESULT)
    theta = tuple(0.5 * (lo + hi) for lo, hi in zip(config.lower, config.upper, strict=True))
    forged = [(CANDIDATE, CandidateMsg("t1", i, theta).encode()) for i in FORGED_IDS] * 25
    legit = [(CANDIDATE, CandidateMsg("t1", i, theta).encode()) for i in range(8)]
    flood(ros, sim, forged + legit, lambda n: dropped(n) + n.counters["episodes"])
    assert sorted(calls) == list(range(8))  # not one episode for a forged id
    assert sim.counters["dropped_id_out_of_range"] == len(forged)
    assert sim.counters["episodes"] == 8
    assert ros.spin_until(lambda: len(results) == 8, 5)
    assert len(sim._thetas) == len(sim._results) == 8
    # a repeat of a run's candidate is served from the stored result
    flood(ros, sim, legit[:1], lambda n: n.counters["results_repeated"])
    assert len(calls) == 8


def forged_traffic(rng: Any, n: int) -> list[tuple[TopicSpec, Any]]:
    """``n`` well-formed results and duel requests of run t1 with ids drawn over 0..10**7."""
    sends: list[tuple[TopicSpec, Any]] = []
    for _ in range(n):
        a, b, d = (int(v) for v in rng.integers(0, 10**7, size=3))
        if rng.random() < 0.5:
            sends.append((EPISODE_RESULT, EpisodeResult.ok("t1", a, float(rng.normal())).encode()))
        else:
            sends.append((DUEL_REQUEST, DuelRequest("t1", d, a, b if b != a else a + 1).encode()))
    return sends


def test_oracle_state_stays_bounded_under_forged_ids(ros: Any) -> None:
    """A flood of forged results and requests (ids up to 10**7, some inside the run's range)
    leaves the oracle's dictionaries within the run's range and the pending window."""
    import numpy as np

    oracle = ros.add(OracleNode(context=ros.ctx, overrides={"max_pending": 16}))
    oracle.warnings.clock = FrozenClock()
    ros.publish(RUN_CONFIG, cheap_config().encode())
    assert ros.spin_until(lambda: oracle.run_id == "t1", 5)
    rng = np.random.default_rng(7)
    sends = forged_traffic(rng, 3000)
    # forged ids inside the range: at most one entry per id of the run
    for i in range(400):
        a, b = int(rng.integers(0, 8)), int(rng.integers(0, 8))
        req = DuelRequest("t1", int(rng.integers(0, 64)), a, b if b != a else (a + 1) % 8)
        sends.append((DUEL_REQUEST, req.encode()))
        sends.append((EPISODE_RESULT, EpisodeResult.ok("t1", i % 8, float(i % 8)).encode()))

    def out_of_range(spec: TopicSpec, msg: Any) -> bool:
        if spec is EPISODE_RESULT:
            res = EpisodeResult.decode(msg)
            return isinstance(res, EpisodeResult) and not res.candidate_id < 16
        req = DuelRequest.decode(msg)
        assert isinstance(req, DuelRequest)
        return not (req.duel_id < 32 and req.first_id < 16 and req.second_id < 16)

    for start in range(0, len(sends), 50):
        for spec, msg in sends[start : start + 50]:
            ros.publish(spec, msg)
        settle(ros, lambda: sum(oracle.counters.values()))
    expected = sum(out_of_range(spec, msg) for spec, msg in sends)
    assert expected >= 3000
    assert oracle.counters["dropped_id_out_of_range"] == expected
    assert len(oracle._results) <= oracle.ids.candidates == 16
    assert len(oracle._answered) <= oracle.ids.duels == 32
    assert len(oracle._waiting) <= 16


class IdleEvaluator(EvaluatorNode):
    """An evaluator that never evaluates (its queue fills)."""

    def adopt(self, config: RunConfig) -> None:
        pass


def test_evaluator_queue_is_bounded_and_repeats_are_counted(ros: Any) -> None:
    node = ros.add(IdleEvaluator("idle_node", [], context=ros.ctx, overrides={"max_pending": 3}))
    node.warnings.clock = FrozenClock()
    config = cheap_config(budget=20)
    ros.publish(RUN_CONFIG, config.encode())
    assert ros.spin_until(lambda: node.run_id == "t1", 5)
    theta = tuple(config.lower)
    other = tuple(config.upper)
    sends = [(CANDIDATE, CandidateMsg("t1", i, theta).encode()) for i in range(6)]
    sends += [(CANDIDATE, CandidateMsg("t1", 1, theta).encode())]  # queued: a repeat
    sends += [(CANDIDATE, CandidateMsg("t1", 2, other).encode())]  # another θ for id 2
    sends += [(CANDIDATE, CandidateMsg("t1", 45, theta).encode())]  # outside the range
    sends += [(CANDIDATE, CandidateMsg("t1", 0, theta, "someone.else").encode())]

    def handled(n: Any) -> int:
        c = n.counters
        return dropped(n) + c["candidates_repeated"] + c["candidates_for_others"] + len(n._queue)

    flood(ros, node, sends, handled)
    assert [c.candidate_id for c in node._queue] == [0, 1, 2]
    c = node.counters
    assert c["dropped_buffer_full"] == 3
    assert c["candidates_repeated"] == 1
    assert c["dropped_conflicting_candidate"] == 1
    assert c["dropped_id_out_of_range"] == 1
    assert c["candidates_for_others"] == 1
    # a refused run fails every candidate at once, none is queued
    node._queue.clear()
    node.refusal_reason = lambda: "target refused"  # type: ignore[method-assign]
    results = ros.collect(EPISODE_RESULT)
    flood(ros, node, [(CANDIDATE, CandidateMsg("t1", 7, theta).encode())], lambda n: len(results))
    decoded = EpisodeResult.decode(results[0])
    assert isinstance(decoded, EpisodeResult) and decoded.error == "target refused"
    assert not node._queue


def test_id_range_follows_the_budget_or_the_config() -> None:
    config = cheap_config(budget=8)
    assert id_range(config) == IdRange(16, 32)
    stated = replace(config, options={**config.options, "ids": {"candidates": 20}})
    assert id_range(stated) == IdRange(20, 40)
    both = replace(config, options={**config.options, "ids": {"candidates": 20, "duels": 5}})
    assert id_range(both) == IdRange(20, 5)
    for bad, field in (
        ({"candidates": 0}, "options.ids.candidates"),
        ({"duels": "9"}, "options.ids.duels"),
        ({"candidate": 3}, "options.ids.candidate"),
    ):
        with pytest.raises(SettingError) as err:
            id_range(replace(config, options={**config.options, "ids": bad}))
        assert err.value.field == field
    assert IdRange(16, 32).duel(31, 0, 15) and not IdRange(16, 32).duel(31, 0, 16)


def test_recorder_holds_a_bounded_backlog_before_the_run_config(
    ros: Any, tmp_path: Any, monkeypatch: Any
) -> None:
    import localpbo_ros.recorder_node as recorder_module

    monkeypatch.setattr(recorder_module, "HOLD_BYTES", 3000)
    path = tmp_path / "early.mcap"
    recorder = start_recorder(ros, path, [RUN_CONFIG, CANDIDATE])
    early = [(CANDIDATE, theta_message(100, candidate=i)) for i in range(5)]  # ~900 B each
    flood(ros, recorder, early, recorder_handled)
    assert len(recorder._held) == 3 and recorder._held_bytes <= 3000
    assert recorder.counters["foreign_before_run"] == 2  # beyond the bound: the oldest out
    flood(ros, recorder, [(RUN_CONFIG, wide_config(100).encode())], recorder_handled)
    assert recorder.counters["recorded"] == 4 and not recorder._held  # config + the 3 held
    recorder.close()
    kept = [CandidateMsg.decode(m.message) for m in read_messages(path, topics=[CANDIDATE.name])]
    assert [c.candidate_id for c in kept if isinstance(c, CandidateMsg)] == [2, 3, 4]
    foreign = read_messages(path, topics=["/localpbo/foreign/candidate"])
    assert [CandidateMsg.decode(m.message).candidate_id for m in foreign] == [0, 1]


@pytest.mark.parametrize("hold_bytes", [0, 3000])
def test_a_run_starting_inside_a_flood_keeps_its_first_candidate(
    ros: Any, tmp_path: Any, monkeypatch: Any, hold_bytes: int
) -> None:
    """The hold is full of earlier traffic (or holds nothing) when the run's config and first
    candidate arrive together; the executor serves the candidate topic first, yet candidate 0
    is recorded as the run's."""
    import localpbo_ros.recorder_node as recorder_module

    monkeypatch.setattr(recorder_module, "HOLD_BYTES", hold_bytes)
    path = tmp_path / "inside.mcap"
    recorder = start_recorder(ros, path, [CANDIDATE, RUN_CONFIG])
    earlier = [(CANDIDATE, theta_message(100, candidate=10**6 + i)) for i in range(8)]
    flood(ros, recorder, earlier, recorder_handled)
    assert recorder.counters["foreign_before_run"] == (8 if hold_bytes == 0 else 5)
    target = recorder_handled(recorder) + 2
    ros.publish(CANDIDATE, theta_message(100, candidate=0))
    ros.publish(RUN_CONFIG, wide_config(100).encode())
    time.sleep(0.5)  # both wait in the recorder's subscriptions before it spins again
    assert ros.spin_until(lambda: recorder_handled(recorder) == target, 20)
    recorder.close()
    kept = [CandidateMsg.decode(m.message) for m in read_messages(path, topics=[CANDIDATE.name])]
    assert [c.candidate_id for c in kept if isinstance(c, CandidateMsg)] == [0]


def test_forged_speculative_candidates_cost_a_bounded_number_of_episodes(ros: Any) -> None:
    from localpbo_ros.sim_node import AHEAD_PER_ID

    from localpbo_msgs_py.topics import SPECULATIVE_CANDIDATE

    calls: list[int] = []

    def evaluator(config: RunConfig, cid: int, theta: Any) -> float:
        calls.append(cid)
        return 1.0

    sim = ros.add(SimNode(context=ros.ctx, evaluator=evaluator))
    sim.warnings.clock = FrozenClock()
    config = cheap_config()
    ros.publish(RUN_CONFIG, config.encode())
    assert ros.spin_until(lambda: sim.run_id == "t1", 5)
    lo, hi = config.lower[0], config.upper[0]
    sends = [
        (
            SPECULATIVE_CANDIDATE,
            CandidateMsg("t1", cid, (lo + (hi - lo) * k / 40, *config.lower[1:])).encode(),
        )
        for cid in (3, 5)
        for k in range(30)
    ]
    sends.append((SPECULATIVE_CANDIDATE, CandidateMsg("t1", 10**7, config.lower).encode()))
    flood(ros, sim, sends, lambda n: dropped(n) + n.counters["episodes_ahead"])
    assert sorted(calls) == [3] * AHEAD_PER_ID + [5] * AHEAD_PER_ID
    assert sim.counters["dropped_ahead_limit"] == 2 * (30 - AHEAD_PER_ID)
    assert sim.counters["dropped_id_out_of_range"] == 1


def test_a_stopped_recorder_takes_its_backlog_first(ros: Any, tmp_path: Any) -> None:
    path = tmp_path / "backlog.mcap"
    recorder = start_recorder(ros, path, [RUN_CONFIG, CANDIDATE])
    flood(ros, recorder, [(RUN_CONFIG, wide_config(100).encode())], recorder_handled)
    for i in range(60):  # published, never spun: waiting in the subscription
        ros.publish(CANDIDATE, theta_message(100, candidate=i))
    time.sleep(0.5)
    assert recorder.counters["recorded"] == 1
    recorder.close()
    kept = [CandidateMsg.decode(m.message) for m in read_messages(path, topics=[CANDIDATE.name])]
    assert [c.candidate_id for c in kept if isinstance(c, CandidateMsg)] == list(range(60))
