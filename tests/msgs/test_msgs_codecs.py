"""Round trips of every schema through encode → CDR → decode, and strict rejections."""

from __future__ import annotations

import math
import re
from collections.abc import Callable
from typing import Any

import numpy as np
import pytest
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rclpy.serialization import deserialize_message, serialize_message
from std_msgs.msg import Float64MultiArray, MultiArrayDimension, String

from localpbo_msgs_py import (
    CandidateMsg,
    DecodeError,
    DecodeReason,
    DuelOutcome,
    DuelRequest,
    EpisodeResult,
    FieldError,
    Incumbent,
    OutcomeKind,
    RunConfig,
    Status,
    is_error,
)


def via_cdr(msg: Any) -> Any:
    """Serialize and deserialize with rclpy, as a subscriber would receive it."""
    return deserialize_message(serialize_message(msg), type(msg))


def random_theta(rng: np.random.Generator, d: int) -> tuple[float, ...]:
    """Values spanning many magnitudes, including subnormals and exact zeros."""
    mags = 10.0 ** rng.integers(-310, 300, size=d)
    vals = rng.standard_normal(d) * mags
    vals[rng.random(d) < 0.1] = 0.0
    return tuple(float(v) for v in vals)


REQ = DuelRequest("run-7", 12, 3, 9)


def all_values(rng: np.random.Generator) -> list[Any]:
    """One instance of every schema, with random content."""
    d = int(rng.integers(1, 40))
    theta = random_theta(rng, d)
    ret = float(rng.standard_normal() * 10.0 ** rng.integers(-300, 300))
    return [
        CandidateMsg("run-7", int(rng.integers(0, 2**63 - 1)), theta),
        Incumbent("run-7", 5, theta, int(rng.integers(0, 10**6))),
        EpisodeResult.ok("run-7", 4, ret),
        EpisodeResult.failed("run-7", 4, "MuJoCo warning: unstable ; = x"),
        REQ,
        DuelOutcome.decisive(REQ, 9),
        DuelOutcome.decisive(REQ, 3),
        DuelOutcome.indifferent(REQ),
        DuelOutcome.failed(REQ, "episode of candidate 9 failed"),
        DuelOutcome.decisive(REQ, 9, answer_seconds=float(rng.exponential(10.0))),
        DuelOutcome.indifferent(REQ, answer_seconds=0.0),
        DuelOutcome.decisive(REQ, 3, answer_seconds=2.5, judge="Ada", note="A limped ✓"),
        DuelOutcome.indifferent(REQ, judge="Bo"),
        DuelOutcome.retracted(REQ),
        RunConfig(
            "run-7",
            "gipbo",
            "hopper",
            d,
            tuple(-abs(v) - 1 for v in theta),
            tuple(abs(v) + 1 for v in theta),
            11,
            300,
            {"lr": 0.25, "nested": {"k": [1, "a", None, True]}},
        ),
        Status(
            "run-7",
            "optimizer",
            "running",
            1,
            "2 messages dropped",
            {"dropped_wrong_run": 2, "duels_done": 40},
            {"algorithm": "gipbo"},
            1_700_000_000_123_456_789,
        ),
    ]


@pytest.mark.parametrize("seed", range(20))
def test_round_trip_every_schema(seed: int) -> None:
    rng = np.random.default_rng(seed)
    for value in all_values(rng):
        received = via_cdr(value.encode())
        decoded = type(value).decode(received, expected_run_id="run-7")
        assert not is_error(decoded), decoded
        assert decoded == value
        # floats survive bit-exactly (text fields use shortest round-trip repr)
        for name in ("theta", "lower", "upper"):
            if hasattr(value, name):
                assert [math.copysign(1, v) for v in getattr(decoded, name)] == [
                    math.copysign(1, v) for v in getattr(value, name)
                ]


def test_candidate_wire_layout_is_plain_float64_multiarray() -> None:
    msg = CandidateMsg("r1", 42, (0.5, -1.25, 3.0)).encode()
    assert isinstance(msg, Float64MultiArray)
    assert list(msg.data) == [0.5, -1.25, 3.0]
    assert msg.layout.data_offset == 0
    (dim,) = msg.layout.dim
    assert (dim.label, dim.size, dim.stride) == ("kind=candidate;run=r1;candidate=42", 3, 3)
    inc = Incumbent("r1", 42, (1.0,), 17).encode()
    assert inc.layout.dim[0].label == "kind=incumbent;run=r1;candidate=42;duels=17"


def test_keyvalue_wire_format() -> None:
    msg = DuelOutcome.decisive(REQ, 9).encode()
    assert isinstance(msg, DiagnosticStatus)
    assert msg.name == "localpbo/duel_outcome" and msg.level == b"\x00"
    assert {kv.key: kv.value for kv in msg.values} == {
        "run_id": "run-7",
        "duel_id": "12",
        "first_id": "3",
        "second_id": "9",
        "kind": "decisive",
        "winner_id": "9",
        "loser_id": "3",
    }
    failed = EpisodeResult.failed("r", 1, "boom").encode()
    assert failed.level == b"\x02"
    ok = EpisodeResult.ok("r", 1, 0.1).encode()
    assert {kv.key: kv.value for kv in ok.values}["episode_return"] == "0.1"


def test_label_keys_accepted_in_any_order() -> None:
    msg = CandidateMsg("r1", 1, (1.0,)).encode()
    msg.layout.dim[0].label = "candidate=1;run=r1;kind=candidate"
    assert CandidateMsg.decode(msg) == CandidateMsg("r1", 1, (1.0,))


# ----------------------------------------------------------------- rejections
def cand(
    label: str = "kind=candidate;run=r1;candidate=3",
    data: Any = (0.1, 0.2),
    size: int | None = None,
    ndims: int = 1,
    offset: int = 0,
) -> Float64MultiArray:
    msg = Float64MultiArray()
    n = len(data) if size is None else size
    msg.layout.dim = [MultiArrayDimension(label=label, size=n, stride=n) for _ in range(ndims)]
    msg.layout.data_offset = offset
    msg.data = list(data)
    return msg


def kv_status(
    name: str, values: dict[str, str] | list[tuple[str, str]], level: int = 0
) -> DiagnosticStatus:
    pairs = values.items() if isinstance(values, dict) else values
    return DiagnosticStatus(
        level=bytes([level]), name=name, values=[KeyValue(key=k, value=v) for k, v in pairs]
    )


EP = {"run_id": "r1", "candidate_id": "3", "status": "ok", "episode_return": "1.5"}
DR = {"run_id": "r1", "duel_id": "0", "first_id": "1", "second_id": "2"}
DO = {**DR, "kind": "decisive", "winner_id": "1", "loser_id": "2"}


def ep(**kw: str | None) -> DiagnosticStatus:
    values = {k: v for k, v in {**EP, **kw}.items() if v is not None}
    return kv_status("localpbo/episode_result", values)


def dreq(**kw: str | None) -> DiagnosticStatus:
    return kv_status(
        "localpbo/duel_request", {k: v for k, v in {**DR, **kw}.items() if v is not None}
    )


def dout(level: int = 0, **kw: str | None) -> DiagnosticStatus:
    return kv_status(
        "localpbo/duel_outcome", {k: v for k, v in {**DO, **kw}.items() if v is not None}, level
    )


GOOD_CONFIG = RunConfig("r1", "gipbo", "hopper", 2, (0.0, -1.0), (1.0, 1.0), 3, 10, {})


def config_json(**kw: Any) -> String:
    import json

    obj = json.loads(GOOD_CONFIG.to_json())
    obj.update(kw)
    for k, v in kw.items():
        if v is None:
            del obj[k]
    return String(data=json.dumps(obj))


def status_msg(values: list[tuple[str, str]], n: int = 1) -> DiagnosticArray:
    msg = DiagnosticArray()
    msg.status = [kv_status("localpbo/optimizer", values) for _ in range(n)]
    return msg


ST = [("run_id", "r1"), ("node", "optimizer"), ("state", "running")]

CASES: list[tuple[str, Callable[[Any], Any], Any, str, str]] = [
    # (case id, decoder, ros message, expected field, expected substring of the problem)
    (
        "cand-wrong-length",
        lambda m: CandidateMsg.decode(m, expected_dim=3),
        cand(),
        "data",
        "length 2, expected 3",
    ),
    ("cand-nan", CandidateMsg.decode, cand(data=(0.1, math.nan)), "data[1]", "finite"),
    ("cand-inf", CandidateMsg.decode, cand(data=(-math.inf, 0.0)), "data[0]", "finite"),
    (
        "cand-negative-id",
        CandidateMsg.decode,
        cand("kind=candidate;run=r1;candidate=-3"),
        "candidate",
        "non-negative integer id",
    ),
    (
        "cand-float-id",
        CandidateMsg.decode,
        cand("kind=candidate;run=r1;candidate=1.5"),
        "candidate",
        "non-negative integer id",
    ),
    (
        "cand-leading-zero-id",
        CandidateMsg.decode,
        cand("kind=candidate;run=r1;candidate=07"),
        "candidate",
        "non-negative integer id",
    ),
    (
        "cand-id-overflow",
        CandidateMsg.decode,
        cand("kind=candidate;run=r1;candidate=9223372036854775808"),
        "candidate",
        "at most",
    ),
    (
        "cand-wrong-run",
        lambda m: CandidateMsg.decode(m, expected_run_id="r2"),
        cand(),
        "run",
        "wrong run",
    ),
    (
        "cand-bad-run-id",
        CandidateMsg.decode,
        cand("kind=candidate;run=a b;candidate=1"),
        "run",
        "not a run id",
    ),
    (
        "cand-above-bound",
        lambda m: CandidateMsg.decode(m, lower=(0, 0), upper=(1, 0.15)),
        cand(),
        "data[1]",
        "above the upper bound",
    ),
    (
        "cand-below-bound",
        lambda m: CandidateMsg.decode(m, lower=(0.5, 0), upper=(1, 1)),
        cand(),
        "data[0]",
        "below the lower bound",
    ),
    (
        "cand-huge",
        lambda m: CandidateMsg.decode(m, max_len=1000),
        cand(data=[0.0] * 1001),
        "data",
        "more than the cap 1000",
    ),
    (
        "cand-huge-default-cap",
        CandidateMsg.decode,
        cand(data=np.zeros(70000)),
        "data",
        "more than the cap 65536",
    ),
    ("cand-empty", CandidateMsg.decode, cand(data=()), "data", "empty"),
    (
        "cand-missing-key",
        CandidateMsg.decode,
        cand("kind=candidate;run=r1"),
        "layout.dim[0].label",
        "missing key 'candidate'",
    ),
    (
        "cand-extra-key",
        CandidateMsg.decode,
        cand("kind=candidate;run=r1;candidate=1;x=2"),
        "layout.dim[0].label",
        "unexpected key 'x'",
    ),
    (
        "cand-dup-key",
        CandidateMsg.decode,
        cand("kind=candidate;run=r1;run=r1;candidate=1"),
        "layout.dim[0].label",
        "more than once",
    ),
    ("cand-not-kv", CandidateMsg.decode, cand("theta"), "layout.dim[0].label", "key=value"),
    (
        "cand-wrong-kind",
        CandidateMsg.decode,
        Incumbent("r1", 1, (1.0,), 0).encode(),
        "layout.dim[0].label",
        "unexpected key 'duels'",
    ),
    ("cand-size-mismatch", CandidateMsg.decode, cand(size=5), "layout.dim[0].size", "is 5"),
    ("cand-two-dims", CandidateMsg.decode, cand(ndims=2), "layout.dim", "exactly 1"),
    ("cand-offset", CandidateMsg.decode, cand(offset=1), "layout.data_offset", "must be 0"),
    (
        "cand-wrong-type",
        CandidateMsg.decode,
        String(data="x"),
        "message",
        "expected std_msgs/msg/Float64MultiArray",
    ),
    ("cand-none", CandidateMsg.decode, None, "message", "got NoneType"),
    (
        "inc-wrong-kind",
        Incumbent.decode,
        cand("kind=candidate;run=r1;candidate=1;duels=3"),
        "layout.dim[0].label",
        "expected 'incumbent'",
    ),
    (
        "inc-negative-duels",
        Incumbent.decode,
        cand("kind=incumbent;run=r1;candidate=1;duels=-1"),
        "duels",
        "non-negative",
    ),
    (
        "ep-missing-return",
        EpisodeResult.decode,
        ep(episode_return=None),
        "episode_return",
        "missing",
    ),
    ("ep-nan-return", EpisodeResult.decode, ep(episode_return="nan"), "episode_return", "finite"),
    ("ep-inf-return", EpisodeResult.decode, ep(episode_return="-inf"), "episode_return", "finite"),
    (
        "ep-text-return",
        EpisodeResult.decode,
        ep(episode_return="fast"),
        "episode_return",
        "not a number",
    ),
    ("ep-bad-status", EpisodeResult.decode, ep(status="great"), "status", "not one of ok, failed"),
    (
        "ep-failed-no-error",
        EpisodeResult.decode,
        kv_status(
            "localpbo/episode_result", {"run_id": "r1", "candidate_id": "3", "status": "failed"}, 2
        ),
        "error",
        "missing",
    ),
    (
        "ep-failed-level-ok",
        EpisodeResult.decode,
        kv_status(
            "localpbo/episode_result",
            {"run_id": "r1", "candidate_id": "3", "status": "failed", "error": "x"},
            0,
        ),
        "level",
        "expected 2",
    ),
    ("ep-unknown-key", EpisodeResult.decode, ep(extra="1"), "extra", "unexpected key"),
    (
        "ep-dup-key",
        EpisodeResult.decode,
        kv_status("localpbo/episode_result", [*EP.items(), ("run_id", "r1")]),
        "run_id",
        "more than once",
    ),
    ("ep-negative-id", EpisodeResult.decode, ep(candidate_id="-1"), "candidate_id", "non-negative"),
    (
        "ep-wrong-run",
        lambda m: EpisodeResult.decode(m, expected_run_id="r9"),
        ep(),
        "run_id",
        "wrong run",
    ),
    (
        "ep-wrong-name",
        EpisodeResult.decode,
        kv_status("localpbo/duel_request", EP),
        "name",
        "expected 'localpbo/episode_result'",
    ),
    (
        "ep-too-many-values",
        EpisodeResult.decode,
        kv_status("localpbo/episode_result", [(f"k{i}", "v") for i in range(65)]),
        "values",
        "cap 64",
    ),
    ("ep-long-value", EpisodeResult.decode, ep(status="x" * 5000), "status", "cap 4096"),
    (
        "ep-wrong-type",
        EpisodeResult.decode,
        DiagnosticArray(),
        "message",
        "expected diagnostic_msgs/msg/DiagnosticStatus",
    ),
    ("req-self-duel", DuelRequest.decode, dreq(second_id="1"), "second_id", "self-duel"),
    (
        "req-negative-seconds",
        DuelRequest.decode,
        dreq(decision_seconds="-0.5"),
        "decision_seconds",
        ">= 0",
    ),
    ("req-nan-seconds", DuelRequest.decode, dreq(decision_seconds="nan"), "decision_seconds", ""),
    ("req-text-seconds", DuelRequest.decode, dreq(decision_seconds="x"), "decision_seconds", ""),
    ("req-missing", DuelRequest.decode, dreq(first_id=None), "first_id", "missing"),
    ("req-hex-id", DuelRequest.decode, dreq(duel_id="0x1"), "duel_id", "integer id"),
    ("req-space-id", DuelRequest.decode, dreq(duel_id=" 1"), "duel_id", "integer id"),
    (
        "req-wrong-run",
        lambda m: DuelRequest.decode(m, expected_run_id="zz"),
        dreq(),
        "run_id",
        "wrong run",
    ),
    (
        "out-winner-not-in-duel",
        DuelOutcome.decode,
        dout(winner_id="5"),
        "winner_id",
        "not the duel's ids",
    ),
    (
        "out-winner-is-loser",
        DuelOutcome.decode,
        dout(loser_id="1"),
        "winner_id",
        "not the duel's ids",
    ),
    ("out-decisive-no-loser", DuelOutcome.decode, dout(loser_id=None), "loser_id", "missing"),
    (
        "out-indifferent-with-winner",
        DuelOutcome.decode,
        dout(kind="indifferent"),
        "winner_id",
        "must be absent",
    ),
    (
        "out-retracted-with-winner",
        DuelOutcome.decode,
        dout(kind="retracted"),
        "winner_id",
        "must be absent",
    ),
    (
        "out-retracted-with-seconds",
        DuelOutcome.decode,
        dout(kind="retracted", winner_id=None, loser_id=None, answer_seconds="1.5"),
        "answer_seconds",
        "must be absent",
    ),
    (
        "out-retracted-with-judge",
        DuelOutcome.decode,
        dout(kind="retracted", winner_id=None, loser_id=None, judge="Ada"),
        "judge",
        "must be absent",
    ),
    (
        "out-failed-with-note",
        DuelOutcome.decode,
        dout(2, kind="failed", winner_id=None, loser_id=None, reason="x", note="hm"),
        "note",
        "must be absent",
    ),
    ("out-note-too-long", DuelOutcome.decode, dout(note="n" * 5000), "note", "more than the cap"),
    (
        "out-retracted-with-reason",
        DuelOutcome.decode,
        dout(kind="retracted", winner_id=None, loser_id=None, reason="oops"),
        "reason",
        "must be absent",
    ),
    (
        "out-retracted-error-level",
        DuelOutcome.decode,
        dout(2, kind="retracted", winner_id=None, loser_id=None),
        "level",
        "expected 0",
    ),
    (
        "out-failed-no-reason",
        DuelOutcome.decode,
        dout(2, kind="failed", winner_id=None, loser_id=None),
        "reason",
        "missing",
    ),
    (
        "out-failed-empty-reason",
        DuelOutcome.decode,
        dout(2, kind="failed", winner_id=None, loser_id=None, reason=""),
        "reason",
        "empty",
    ),
    ("out-unknown-kind", DuelOutcome.decode, dout(kind="tie"), "kind", "not one of decisive"),
    (
        "out-answer-seconds-negative",
        DuelOutcome.decode,
        dout(answer_seconds="-0.5"),
        "answer_seconds",
        "must be >= 0",
    ),
    (
        "out-answer-seconds-nan",
        DuelOutcome.decode,
        dout(answer_seconds="nan"),
        "answer_seconds",
        "must be finite",
    ),
    (
        "out-answer-seconds-text",
        DuelOutcome.decode,
        dout(answer_seconds="soon"),
        "answer_seconds",
        "not a number",
    ),
    (
        "out-answer-seconds-when-failed",
        DuelOutcome.decode,
        dout(2, kind="failed", winner_id=None, loser_id=None, reason="x", answer_seconds="1.0"),
        "answer_seconds",
        "must be absent when kind is failed",
    ),
    (
        "out-wrong-run",
        lambda m: DuelOutcome.decode(m, expected_run_id="r0"),
        dout(),
        "run_id",
        "wrong run",
    ),
    ("cfg-not-json", RunConfig.decode, String(data="{not json"), "data", "not JSON"),
    (
        "cfg-nan",
        RunConfig.decode,
        String(data=GOOD_CONFIG.to_json().replace('"seed": 3', '"seed": NaN')),
        "data",
        "NaN",
    ),
    (
        "cfg-dup-key",
        RunConfig.decode,
        String(data=GOOD_CONFIG.to_json()[:-1] + ', "seed": 4}'),
        "data",
        "key 'seed' appears more than once",
    ),
    ("cfg-array", RunConfig.decode, String(data="[1, 2]"), "data", "JSON object"),
    ("cfg-missing", RunConfig.decode, config_json(budget=None), "budget", "missing"),
    ("cfg-extra", RunConfig.decode, config_json(colour="red"), "colour", "unexpected key"),
    ("cfg-schema", RunConfig.decode, config_json(schema="other/v9"), "schema", "expected"),
    ("cfg-dim-mismatch", RunConfig.decode, config_json(dim=3), "lower", "expected 3"),
    ("cfg-empty-box", RunConfig.decode, config_json(upper=[0.0, 1.0]), "upper[0]", "must exceed"),
    ("cfg-negative-seed", RunConfig.decode, config_json(seed=-1), "seed", "non-negative"),
    ("cfg-bool-dim", RunConfig.decode, config_json(dim=True), "dim", "integer"),
    ("cfg-float-budget", RunConfig.decode, config_json(budget=10.5), "budget", "integer"),
    ("cfg-string-bound", RunConfig.decode, config_json(lower=["0", "0"]), "lower[0]", "number"),
    ("cfg-options-list", RunConfig.decode, config_json(options=[1]), "options", "object"),
    (
        "cfg-wrong-run",
        lambda m: RunConfig.decode(m, expected_run_id="q"),
        GOOD_CONFIG.encode(),
        "run_id",
        "wrong run",
    ),
    ("cfg-huge", RunConfig.decode, String(data=" " * (2**20 + 1)), "data", "cap 1048576"),
    ("st-two-entries", Status.decode, status_msg(ST, 2), "status", "exactly 1"),
    ("st-missing-state", Status.decode, status_msg(ST[:2]), "state", "missing"),
    (
        "st-negative-counter",
        Status.decode,
        status_msg([*ST, ("count.dropped", "-1")]),
        "count.dropped",
        "non-negative",
    ),
    (
        "st-unknown-key",
        Status.decode,
        status_msg([*ST, ("colour", "red")]),
        "colour",
        "unexpected key",
    ),
    (
        "st-bad-node",
        Status.decode,
        status_msg([("run_id", "r1"), ("node", "Opt!")]),
        "node",
        "not a name",
    ),
    (
        "st-wrong-run",
        lambda m: Status.decode(m, expected_run_id="r2"),
        status_msg(ST),
        "run_id",
        "wrong run",
    ),
]


_R = DecodeReason
REASONS: dict[str, DecodeReason] = {
    "cand-wrong-length": _R.WRONG_SHAPE,
    "cand-nan": _R.NON_FINITE,
    "cand-inf": _R.NON_FINITE,
    "cand-negative-id": _R.MALFORMED,
    "cand-float-id": _R.MALFORMED,
    "cand-leading-zero-id": _R.MALFORMED,
    "cand-id-overflow": _R.OUT_OF_BOUNDS,
    "cand-wrong-run": _R.WRONG_RUN,
    "cand-bad-run-id": _R.MALFORMED,
    "cand-above-bound": _R.OUT_OF_BOUNDS,
    "cand-below-bound": _R.OUT_OF_BOUNDS,
    "cand-huge": _R.TOO_LARGE,
    "cand-huge-default-cap": _R.TOO_LARGE,
    "cand-empty": _R.WRONG_SHAPE,
    "cand-missing-key": _R.MALFORMED,
    "cand-extra-key": _R.MALFORMED,
    "cand-dup-key": _R.MALFORMED,
    "cand-not-kv": _R.MALFORMED,
    "cand-wrong-kind": _R.MALFORMED,
    "cand-size-mismatch": _R.INCONSISTENT,
    "cand-two-dims": _R.MALFORMED,
    "cand-offset": _R.MALFORMED,
    "cand-wrong-type": _R.WRONG_TYPE,
    "cand-none": _R.WRONG_TYPE,
    "inc-wrong-kind": _R.MALFORMED,
    "inc-negative-duels": _R.MALFORMED,
    "ep-missing-return": _R.MALFORMED,
    "ep-nan-return": _R.NON_FINITE,
    "ep-inf-return": _R.NON_FINITE,
    "ep-text-return": _R.MALFORMED,
    "ep-bad-status": _R.MALFORMED,
    "ep-failed-no-error": _R.MALFORMED,
    "ep-failed-level-ok": _R.INCONSISTENT,
    "ep-unknown-key": _R.MALFORMED,
    "ep-dup-key": _R.MALFORMED,
    "ep-negative-id": _R.MALFORMED,
    "ep-wrong-run": _R.WRONG_RUN,
    "ep-wrong-name": _R.MALFORMED,
    "ep-too-many-values": _R.TOO_LARGE,
    "ep-long-value": _R.TOO_LARGE,
    "ep-wrong-type": _R.WRONG_TYPE,
    "req-self-duel": _R.INCONSISTENT,
    "req-negative-seconds": _R.OUT_OF_BOUNDS,
    "req-nan-seconds": _R.NON_FINITE,
    "req-text-seconds": _R.MALFORMED,
    "req-missing": _R.MALFORMED,
    "req-hex-id": _R.MALFORMED,
    "req-space-id": _R.MALFORMED,
    "req-wrong-run": _R.WRONG_RUN,
    "out-winner-not-in-duel": _R.INCONSISTENT,
    "out-winner-is-loser": _R.INCONSISTENT,
    "out-decisive-no-loser": _R.MALFORMED,
    "out-indifferent-with-winner": _R.MALFORMED,
    "out-retracted-with-winner": _R.MALFORMED,
    "out-retracted-with-seconds": _R.MALFORMED,
    "out-retracted-with-reason": _R.MALFORMED,
    "out-retracted-with-judge": _R.MALFORMED,
    "out-failed-with-note": _R.MALFORMED,
    "out-note-too-long": _R.TOO_LARGE,
    "out-retracted-error-level": _R.INCONSISTENT,
    "out-failed-no-reason": _R.MALFORMED,
    "out-failed-empty-reason": _R.MALFORMED,
    "out-unknown-kind": _R.MALFORMED,
    "out-wrong-run": _R.WRONG_RUN,
    "out-answer-seconds-negative": _R.OUT_OF_BOUNDS,
    "out-answer-seconds-nan": _R.NON_FINITE,
    "out-answer-seconds-text": _R.MALFORMED,
    "out-answer-seconds-when-failed": _R.MALFORMED,
    "cfg-not-json": _R.MALFORMED,
    "cfg-nan": _R.NON_FINITE,
    "cfg-dup-key": _R.MALFORMED,
    "cfg-array": _R.WRONG_TYPE,
    "cfg-missing": _R.MALFORMED,
    "cfg-extra": _R.MALFORMED,
    "cfg-schema": _R.MALFORMED,
    "cfg-dim-mismatch": _R.WRONG_SHAPE,
    "cfg-empty-box": _R.INCONSISTENT,
    "cfg-negative-seed": _R.OUT_OF_BOUNDS,
    "cfg-bool-dim": _R.WRONG_TYPE,
    "cfg-float-budget": _R.WRONG_TYPE,
    "cfg-string-bound": _R.WRONG_TYPE,
    "cfg-options-list": _R.WRONG_TYPE,
    "cfg-wrong-run": _R.WRONG_RUN,
    "cfg-huge": _R.TOO_LARGE,
    "st-two-entries": _R.MALFORMED,
    "st-missing-state": _R.MALFORMED,
    "st-negative-counter": _R.MALFORMED,
    "st-unknown-key": _R.MALFORMED,
    "st-bad-node": _R.MALFORMED,
    "st-wrong-run": _R.WRONG_RUN,
}
"""The reason each rejection of CASES carries (nodes count drops by it)."""


@pytest.mark.parametrize(
    ("decoder", "msg", "field", "problem", "reason"),
    [(*c[1:], REASONS[c[0]]) for c in CASES],
    ids=[c[0] for c in CASES],
)
def test_rejections_name_the_problem(
    decoder: Callable[[Any], Any], msg: Any, field: str, problem: str, reason: DecodeReason
) -> None:
    result = decoder(msg)
    assert isinstance(result, DecodeError), result
    assert result.field == field, str(result)
    assert result.reason is reason, str(result)
    assert problem in result.problem, str(result)
    assert field in str(result)


def test_every_reason_is_exercised_and_every_case_has_one() -> None:
    assert set(REASONS) == {c[0] for c in CASES}
    assert set(REASONS.values()) == set(DecodeReason)


def test_undecodable_message_is_malformed() -> None:
    class Exploding(Float64MultiArray):
        def __init__(self) -> None:  # no field set up: any read below raises
            pass

        @property
        def layout(self) -> Any:
            raise RuntimeError("boom")

    result = CandidateMsg.decode(Exploding())
    assert isinstance(result, DecodeError)
    assert result.reason is DecodeReason.MALFORMED and "undecodable" in result.problem


def test_rejection_survives_cdr() -> None:
    """The same rejections happen after a real CDR round trip (NaN travels as NaN)."""
    result = CandidateMsg.decode(via_cdr(cand(data=(0.1, math.nan))))
    assert isinstance(result, DecodeError) and result.field == "data[1]"


def test_good_messages_built_by_hand_decode() -> None:
    """The hand-built fixtures above are valid when unmodified (the rejections are specific)."""
    assert CandidateMsg.decode(
        cand(), expected_run_id="r1", expected_dim=2, lower=(0, 0), upper=(1, 1)
    ) == CandidateMsg("r1", 3, (0.1, 0.2))
    assert EpisodeResult.decode(ep()) == EpisodeResult.ok("r1", 3, 1.5)
    assert DuelRequest.decode(dreq()) == DuelRequest("r1", 0, 1, 2)
    assert DuelOutcome.decode(dout()) == DuelOutcome("r1", 0, 1, 2, OutcomeKind.DECISIVE, 1, 2)
    timed = DuelOutcome.decode(dout(answer_seconds="12.5"))
    assert isinstance(timed, DuelOutcome) and timed.answer_seconds == 12.5
    assert DuelOutcome.decode(
        dout(kind="indifferent", winner_id=None, loser_id=None, answer_seconds="3")
    ) == DuelOutcome("r1", 0, 1, 2, OutcomeKind.INDIFFERENT, answer_seconds=3.0)
    assert DuelOutcome.decode(dout(kind="retracted", winner_id=None, loser_id=None)) == DuelOutcome(
        "r1", 0, 1, 2, OutcomeKind.RETRACTED
    )
    assert RunConfig.decode(config_json()) == GOOD_CONFIG
    assert Status.decode(status_msg(ST)) == Status("r1", "optimizer", "running")


@pytest.mark.parametrize(
    ("build", "text"),
    [
        (lambda: CandidateMsg("r1", -1, (1.0,)), "candidate_id"),
        (lambda: CandidateMsg("r1", 1, (math.nan,)), "theta[0]"),
        (lambda: CandidateMsg("", 1, (1.0,)), "run_id"),
        (lambda: Incumbent("r1", 1, (), 0), "theta"),
        (lambda: EpisodeResult("r1", 1, "ok"), "episode_return"),
        (lambda: EpisodeResult("r1", 1, "meh", 1.0), "status"),
        (lambda: DuelRequest("r1", 0, 2, 2), "self-duel"),
        (lambda: DuelOutcome.decisive(REQ, 4), "not the duel's ids"),
        (lambda: DuelOutcome.failed(REQ, ""), "reason"),
        (lambda: DuelOutcome.decisive(REQ, 9, answer_seconds=-1.0), "answer_seconds"),
        (lambda: DuelOutcome.decisive(REQ, 9, answer_seconds=math.inf), "answer_seconds"),
        (
            lambda: DuelOutcome(
                REQ.run_id, 0, 3, 9, OutcomeKind.FAILED, reason="x", answer_seconds=1.0
            ),
            "answer_seconds",
        ),
        (lambda: RunConfig("r1", "a", "t", 1, (0.0,), (1.0,), 0, 1, {"x": math.inf}), "options"),
        (lambda: Status("r1", "optimizer", "running", counters={"n": -2}), "count.n"),
        (lambda: Status("r1", "optimizer", "running", level=7), "level"),
    ],
)
def test_encoders_raise_value_error(build: Callable[[], Any], text: str) -> None:
    with pytest.raises(ValueError, match=re.escape(text)) as info:
        build()
    assert isinstance(info.value, FieldError) and isinstance(info.value.reason, DecodeReason)


def test_decoders_never_raise_on_garbage() -> None:
    """Randomised hostile messages: every decoder returns a value or a DecodeError."""
    rng = np.random.default_rng(1234)
    alphabet = list("kind=candidateincumbentrun;01-9.xyz \x00é")
    decoders = [
        CandidateMsg.decode,
        Incumbent.decode,
        EpisodeResult.decode,
        DuelRequest.decode,
        DuelOutcome.decode,
        RunConfig.decode,
        Status.decode,
    ]
    keys = [
        "run_id",
        "candidate_id",
        "status",
        "episode_return",
        "error",
        "duel_id",
        "first_id",
        "second_id",
        "kind",
        "winner_id",
        "loser_id",
        "reason",
        "node",
        "state",
        "count.x",
        "info.y",
    ]

    def text() -> str:
        return "".join(rng.choice(alphabet, size=int(rng.integers(0, 12))))

    for _ in range(300):
        which = int(rng.integers(0, 4))
        if which == 0:
            msg: Any = cand(
                text(),
                data=rng.standard_normal(int(rng.integers(0, 4))),
                size=int(rng.integers(0, 5)),
            )
        elif which == 1:
            names = [
                "localpbo/episode_result",
                "localpbo/duel_request",
                "localpbo/duel_outcome",
                text(),
            ]
            msg = kv_status(
                str(rng.choice(names)),
                [(str(rng.choice(keys)), text()) for _ in range(rng.integers(0, 9))],
                int(rng.integers(0, 4)),
            )
        elif which == 2:
            msg = String(data=text())
        else:
            msg = status_msg([(str(rng.choice(keys)), text()) for _ in range(rng.integers(0, 6))])
        for decode in decoders:
            out = decode(msg)
            assert isinstance(out, DecodeError) or type(out).__name__ in {
                "CandidateMsg",
                "Incumbent",
                "EpisodeResult",
                "DuelRequest",
                "DuelOutcome",
                "RunConfig",
                "Status",
            }


def test_decision_seconds_round_trip_and_do_not_change_the_duel() -> None:
    timed = DuelRequest("r1", 4, 1, 2, decision_seconds=0.0123)
    back = DuelRequest.decode(via_cdr(timed.encode()))
    assert isinstance(back, DuelRequest) and back.decision_seconds == 0.0123
    assert back == DuelRequest("r1", 4, 1, 2)  # a measurement, not part of the duel
    plain = DuelRequest.decode(via_cdr(DuelRequest("r1", 4, 1, 2).encode()))
    assert isinstance(plain, DuelRequest) and plain.decision_seconds is None
    assert REQ.with_decision_seconds(1.5).decision_seconds == 1.5
    with pytest.raises(FieldError):
        DuelRequest("r1", 4, 1, 2, decision_seconds=-1.0)
