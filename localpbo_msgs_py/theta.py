"""θ-carrying messages: ``CandidateMsg`` and ``Incumbent`` on ``std_msgs/msg/Float64MultiArray``.

Wire mapping: ``data`` is θ in the task's own units, so a ros2_control forward
controller can consume the message unchanged. The ids travel in the one layout dimension::

    layout.data_offset  = 0
    layout.dim          = [MultiArrayDimension(label=LABEL, size=len(data), stride=len(data))]
    LABEL (candidate)   = "kind=candidate;run=<run_id>;candidate=<candidate_id>[;worker=<id>]"
    LABEL (incumbent)   = "kind=incumbent;run=<run_id>;candidate=<candidate_id>;duels=<n_duels>"

``<candidate_id>`` and ``<n_duels>`` are non-negative decimal integers without sign or leading
zeros. Writers emit the keys in the order shown; readers accept any order but require exactly
this key set (``worker`` is optional).

``worker`` assigns the candidate to one evaluator of a pool (its worker id, with the run-id
grammar ``[A-Za-z0-9][A-Za-z0-9_.-]{0,63}``); without it (older messages, a single evaluator)
any evaluator may take the candidate. Who evaluates never changes the result: the episode seed
depends only on the run seed and the candidate id.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import TypedDict, Unpack

from std_msgs.msg import Float64MultiArray, MultiArrayDimension

from localpbo_msgs_py._guard import check_type, guarded
from localpbo_msgs_py._validate import (
    MAX_TEXT,
    MAX_THETA_LEN,
    check_cap,
    check_expected_run,
    check_id,
    check_run_id,
    check_vector,
    parse_id,
    repeated_key,
    require_keys,
)
from localpbo_msgs_py.errors import DecodeError, DecodeReason, FieldError

TYPE_NAME = "std_msgs/msg/Float64MultiArray"
LABEL_FIELD = "layout.dim[0].label"


def format_label(pairs: Sequence[tuple[str, str]]) -> str:
    """``key=value`` pairs joined by ``;`` (the layout label grammar)."""
    return ";".join(f"{k}={v}" for k, v in pairs)


def parse_label(label: str, keys: Sequence[str], optional: Sequence[str] = ()) -> dict[str, str]:
    """Parse a layout label; exactly ``keys`` (and any of ``optional``) must be present, each
    once."""
    check_cap(len(label), MAX_TEXT, LABEL_FIELD, "characters")
    out: dict[str, str] = {}
    for part in label.split(";"):
        key, sep, value = part.partition("=")
        if not sep:
            raise FieldError(
                LABEL_FIELD,
                DecodeReason.MALFORMED,
                f"{part[:80]!r} is not key=value (label {label[:120]!r})",
            )
        if key in out:
            raise repeated_key(LABEL_FIELD, key)
        out[key] = value
    require_keys(out, keys, optional, field=LABEL_FIELD)
    return out


def _theta_message(label: str, theta: Sequence[float]) -> Float64MultiArray:
    n = len(theta)
    msg = Float64MultiArray()
    msg.layout.dim = [MultiArrayDimension(label=label, size=n, stride=n)]
    msg.layout.data_offset = 0
    msg.data = [float(v) for v in theta]
    return msg


class ThetaChecks(TypedDict, total=False):
    """What a decoded theta message must match: its run (``expected_run_id``), its length
    (``expected_dim``), inclusive bounds in task units (``lower``, ``upper``) and at most
    ``max_len`` entries (default :data:`MAX_THETA_LEN`)."""

    expected_run_id: str | None
    expected_dim: int | None
    lower: Sequence[float] | None
    upper: Sequence[float] | None
    max_len: int


def _read_theta(
    msg: object,
    kind: str,
    keys: Sequence[str],
    optional: Sequence[str] = (),
    *,
    expected_run_id: str | None = None,
    expected_dim: int | None = None,
    lower: Sequence[float] | None = None,
    upper: Sequence[float] | None = None,
    max_len: int = MAX_THETA_LEN,
) -> tuple[str, dict[str, str], tuple[float, ...]]:
    """The run id (checked against ``expected_run_id``), the label's fields and theta of a
    ``kind`` message."""
    check_type(msg, Float64MultiArray, TYPE_NAME)
    assert isinstance(msg, Float64MultiArray)
    dims = msg.layout.dim
    if len(dims) != 1:
        raise FieldError(
            "layout.dim", DecodeReason.MALFORMED, f"must have exactly 1 dimension, has {len(dims)}"
        )
    if msg.layout.data_offset != 0:
        raise FieldError(
            "layout.data_offset", DecodeReason.MALFORMED, f"must be 0, got {msg.layout.data_offset}"
        )
    fields = parse_label(dims[0].label, keys, optional)
    if fields["kind"] != kind:
        raise FieldError(
            LABEL_FIELD,
            DecodeReason.MALFORMED,
            f"kind is {fields['kind'][:40]!r}, expected {kind!r}",
        )
    n = len(msg.data)
    check_cap(n, max_len, "data", "entries")
    for name, value in (("size", dims[0].size), ("stride", dims[0].stride)):
        if value != n:
            raise FieldError(
                f"layout.dim[0].{name}",
                DecodeReason.INCONSISTENT,
                f"is {value}, data has {n} entries",
            )
    theta = check_vector(
        msg.data, "data", expected_len=expected_dim, lower=lower, upper=upper, max_len=max_len
    )
    run_id = check_run_id(fields["run"], "run")
    check_expected_run(run_id, expected_run_id, "run")
    return run_id, fields, theta


@dataclass(frozen=True)
class CandidateMsg:
    """A candidate to evaluate: θ (task units) with its run id and candidate id.

    Topic ``/localpbo/candidate`` (optimizer → simulator / your controller). ``worker`` is
    the evaluator it is assigned to (empty: anyone).
    """

    run_id: str
    candidate_id: int
    theta: tuple[float, ...]
    worker: str = ""

    def __post_init__(self) -> None:
        check_run_id(self.run_id)
        check_id(self.candidate_id, "candidate_id")
        object.__setattr__(self, "theta", check_vector(self.theta, "theta"))
        if self.worker:
            check_run_id(self.worker, "worker")

    def assigned_to(self, worker: str) -> CandidateMsg:
        """The same candidate assigned to ``worker`` (empty: anyone)."""
        return CandidateMsg(self.run_id, self.candidate_id, self.theta, worker)

    def encode(self) -> Float64MultiArray:
        """The ROS message (see module docstring for the layout label)."""
        pairs = [("kind", "candidate"), ("run", self.run_id), ("candidate", str(self.candidate_id))]
        if self.worker:
            pairs.append(("worker", self.worker))
        return _theta_message(format_label(pairs), self.theta)

    @classmethod
    def decode(cls, msg: object, **checks: Unpack[ThetaChecks]) -> CandidateMsg | DecodeError:
        """Validate and decode (see :class:`ThetaChecks`)."""

        def body() -> CandidateMsg:
            keys = ("kind", "run", "candidate")
            run_id, fields, theta = _read_theta(msg, "candidate", keys, ("worker",), **checks)
            cid = parse_id(fields["candidate"], "candidate")
            worker = check_run_id(fields["worker"], "worker") if "worker" in fields else ""
            return cls(run_id, cid, theta, worker)

        return guarded("candidate", body)


@dataclass(frozen=True)
class Incumbent:
    """The current best candidate (from preferences only) after ``n_duels`` outcomes.

    Topic ``/localpbo/incumbent`` (transient-local, depth 1: late joiners get the latest).
    """

    run_id: str
    candidate_id: int
    theta: tuple[float, ...]
    n_duels: int

    def __post_init__(self) -> None:
        check_run_id(self.run_id)
        check_id(self.candidate_id, "candidate_id")
        check_id(self.n_duels, "n_duels")
        object.__setattr__(self, "theta", check_vector(self.theta, "theta"))

    def encode(self) -> Float64MultiArray:
        """The ROS message (see module docstring for the layout label)."""
        label = format_label(
            [
                ("kind", "incumbent"),
                ("run", self.run_id),
                ("candidate", str(self.candidate_id)),
                ("duels", str(self.n_duels)),
            ]
        )
        return _theta_message(label, self.theta)

    @classmethod
    def decode(cls, msg: object, **checks: Unpack[ThetaChecks]) -> Incumbent | DecodeError:
        """Validate and decode (see :class:`ThetaChecks`)."""

        def body() -> Incumbent:
            keys = ("kind", "run", "candidate", "duels")
            run_id, fields, theta = _read_theta(msg, "incumbent", keys, **checks)
            cid = parse_id(fields["candidate"], "candidate")
            n_duels = parse_id(fields["duels"], "duels")
            return cls(run_id, cid, theta, n_duels)

        return guarded("incumbent", body)
