"""Episode results, duel requests and duel outcomes on ``diagnostic_msgs/msg/DiagnosticStatus``.

Each schema is a DiagnosticStatus whose ``name`` identifies the schema and whose ``values``
(KeyValue pairs, each key at most once, order free) carry the fields as text:

* ids: non-negative decimal integers, no sign, no leading zeros (``"0"``, ``"17"``);
* floats: shortest round-trip text (Python ``repr``, C++ ``std::to_chars``/``%.17g``), finite;
* ``level``: ``OK`` (0) unless the record reports a failure, then ``ERROR`` (2);
* ``message``: free human-readable text, ignored by decoders; ``hardware_id``: ``""``.

Unknown or duplicate keys are rejected.
"""

from __future__ import annotations

import abc
from dataclasses import dataclass, field, replace
from enum import StrEnum
from functools import partial
from typing import ClassVar, Self, TypeVar

from diagnostic_msgs.msg import DiagnosticStatus

from localpbo_msgs_py._diag import LEVEL_ERROR, LEVEL_OK, make_status, read_status
from localpbo_msgs_py._guard import guarded
from localpbo_msgs_py._validate import (
    check_expected_run,
    check_finite,
    check_id,
    check_run_id,
    check_text,
    format_float,
    parse_float,
    parse_id,
    require_keys,
)
from localpbo_msgs_py.errors import DecodeError, DecodeReason, FieldError

EPISODE_RESULT_NAME = "localpbo/episode_result"
DUEL_REQUEST_NAME = "localpbo/duel_request"
DUEL_OUTCOME_NAME = "localpbo/duel_outcome"


R = DecodeReason


def _check_level(level: int, expected: int) -> None:
    if level != expected:
        raise FieldError(
            "level", R.INCONSISTENT, f"is {level}, expected {expected} for this record"
        )


def _check_distinct(first_id: int, second_id: int) -> None:
    if first_id == second_id:
        raise FieldError("second_id", R.INCONSISTENT, f"equals first_id ({first_id}): self-duel")


def _check_seconds(value: object, field: str) -> float:
    """A duration: finite and >= 0."""
    seconds = check_finite(value, field)
    if seconds < 0:
        raise FieldError(field, R.OUT_OF_BOUNDS, f"is {seconds!r}, must be >= 0")
    return seconds


def _require(condition: bool, field: str, problem: str) -> None:
    """Raise ``FieldError`` (``INCONSISTENT``) unless ``condition``: a field that must be
    present, absent or empty because of another field."""
    if not condition:
        raise FieldError(field, R.INCONSISTENT, problem)


E = TypeVar("E", bound=StrEnum)


def _enum(cls: type[E], value: object, field: str) -> E:
    if isinstance(value, str):
        for member in cls:
            if member.value == value:
                return member
    allowed = ", ".join(m.value for m in cls)
    shown = value[:40] if isinstance(value, str) else value
    raise FieldError(field, R.MALFORMED, f"{shown!r} is not one of {allowed}")


def _check_duel(duel: DuelRequest | DuelOutcome) -> None:
    """Check the fields a duel request and its outcome share."""
    check_run_id(duel.run_id)
    check_id(duel.duel_id, "duel_id")
    check_id(duel.first_id, "first_id")
    check_id(duel.second_id, "second_id")
    _check_distinct(duel.first_id, duel.second_id)


def _duel_values(duel: DuelRequest | DuelOutcome) -> dict[str, str]:
    """The keys a duel request and its outcome share, as text."""
    return {
        "run_id": duel.run_id,
        "duel_id": str(duel.duel_id),
        "first_id": str(duel.first_id),
        "second_id": str(duel.second_id),
    }


class _StatusRecord(abc.ABC):
    """A record carried by a DiagnosticStatus named :attr:`STATUS_NAME` (module docstring);
    :meth:`decode` reads the status and hands its level and values to :meth:`_from_status`."""

    STATUS_NAME: ClassVar[str]
    SCHEMA: ClassVar[str]

    @classmethod
    def decode(cls, msg: object, *, expected_run_id: str | None = None) -> Self | DecodeError:
        """Validate and decode."""
        return guarded(cls.SCHEMA, partial(cls._read, msg, expected_run_id))

    @classmethod
    def _read(cls, msg: object, expected_run_id: str | None) -> Self:
        level, _, values = read_status(msg, cls.STATUS_NAME)
        return cls._from_status(level, values, expected_run_id)

    @classmethod
    @abc.abstractmethod
    def _from_status(cls, level: int, v: dict[str, str], expected_run_id: str | None) -> Self:
        """The record of a status's ``level`` and values ``v`` (FieldError if invalid)."""


class EpisodeStatus(StrEnum):
    """Whether the episode ran (``ok``) or could not be evaluated (``failed``)."""

    OK = "ok"
    FAILED = "failed"


@dataclass(frozen=True)
class EpisodeResult(_StatusRecord):
    """The outcome of running one candidate's episode (simulator → oracle).

    Keys: ``run_id``, ``candidate_id``, ``status`` (``ok``|``failed``), ``episode_return``
    (finite float, iff ``ok``), ``error`` (non-empty text, iff ``failed``).
    """

    STATUS_NAME = EPISODE_RESULT_NAME
    SCHEMA = "episode_result"

    run_id: str
    candidate_id: int
    status: EpisodeStatus
    episode_return: float | None = None
    error: str = ""

    def __post_init__(self) -> None:
        check_run_id(self.run_id)
        check_id(self.candidate_id, "candidate_id")
        object.__setattr__(self, "status", _enum(EpisodeStatus, self.status, "status"))
        if self.status is EpisodeStatus.OK:
            _require(
                self.episode_return is not None, "episode_return", "required when status is ok"
            )
            object.__setattr__(
                self, "episode_return", check_finite(self.episode_return, "episode_return")
            )
            _require(not self.error, "error", "must be empty when status is ok")
        else:
            _require(
                self.episode_return is None,
                "episode_return",
                "must be absent when status is failed",
            )
            check_text(self.error, "error", allow_empty=False)

    @classmethod
    def ok(cls, run_id: str, candidate_id: int, episode_return: float) -> EpisodeResult:
        """A successful episode."""
        return cls(run_id, candidate_id, EpisodeStatus.OK, episode_return)

    @classmethod
    def failed(cls, run_id: str, candidate_id: int, error: str) -> EpisodeResult:
        """An episode that could not be evaluated (simulator error, timeout, ...)."""
        return cls(run_id, candidate_id, EpisodeStatus.FAILED, None, error)

    def encode(self) -> DiagnosticStatus:
        """The ROS message."""
        values = {
            "run_id": self.run_id,
            "candidate_id": str(self.candidate_id),
            "status": self.status.value,
        }
        if self.status is EpisodeStatus.OK:
            assert self.episode_return is not None
            values["episode_return"] = format_float(self.episode_return)
            return make_status(EPISODE_RESULT_NAME, LEVEL_OK, "ok", values)
        values["error"] = self.error
        return make_status(EPISODE_RESULT_NAME, LEVEL_ERROR, self.error, values)

    @classmethod
    def _from_status(
        cls, level: int, v: dict[str, str], expected_run_id: str | None
    ) -> EpisodeResult:
        require_keys(v, ("run_id", "candidate_id", "status"), ("episode_return", "error"))
        run_id = check_run_id(v["run_id"])
        check_expected_run(run_id, expected_run_id)
        cid = parse_id(v["candidate_id"], "candidate_id")
        status = _enum(EpisodeStatus, v["status"], "status")
        if status is EpisodeStatus.OK:
            require_keys(
                v,
                ("run_id", "candidate_id", "status", "episode_return"),
                context=" (must be absent when status is ok)",
            )
            _check_level(level, LEVEL_OK)
            return cls.ok(run_id, cid, parse_float(v["episode_return"], "episode_return"))
        require_keys(
            v,
            ("run_id", "candidate_id", "status", "error"),
            context=" (must be absent when status is failed)",
        )
        _check_level(level, LEVEL_ERROR)
        return cls.failed(run_id, cid, v["error"])


@dataclass(frozen=True)
class DuelRequest(_StatusRecord):
    """Ask the oracle to compare two evaluated candidates (optimizer → oracle).

    Keys: ``run_id``, ``duel_id``, ``first_id``, ``second_id`` (distinct candidate ids);
    optional ``decision_seconds`` (finite, >= 0): how long the optimizer took to decide the ask
    this duel belongs to, from the answer that completed the previous ask (or from the start)
    to the request — the wait a person judging the duels sees. It is a measurement, not part
    of the duel: requests that differ only in it compare equal.
    """

    STATUS_NAME = DUEL_REQUEST_NAME
    SCHEMA = "duel_request"

    run_id: str
    duel_id: int
    first_id: int
    second_id: int
    decision_seconds: float | None = field(default=None, compare=False)

    def __post_init__(self) -> None:
        _check_duel(self)
        if self.decision_seconds is not None:
            _check_seconds(self.decision_seconds, "decision_seconds")

    def with_decision_seconds(self, seconds: float | None) -> DuelRequest:
        """This request carrying ``seconds`` as its decision time."""
        return replace(self, decision_seconds=seconds)

    def encode(self) -> DiagnosticStatus:
        """The ROS message."""
        values = _duel_values(self)
        if self.decision_seconds is not None:
            values["decision_seconds"] = format_float(self.decision_seconds)
        return make_status(DUEL_REQUEST_NAME, LEVEL_OK, "", values)

    @classmethod
    def _from_status(
        cls, level: int, v: dict[str, str], expected_run_id: str | None
    ) -> DuelRequest:
        require_keys(v, ("run_id", "duel_id", "first_id", "second_id"), ("decision_seconds",))
        _check_level(level, LEVEL_OK)
        run_id = check_run_id(v["run_id"])
        check_expected_run(run_id, expected_run_id)
        seconds = v.get("decision_seconds")
        return cls(
            run_id,
            parse_id(v["duel_id"], "duel_id"),
            parse_id(v["first_id"], "first_id"),
            parse_id(v["second_id"], "second_id"),
            None if seconds is None else parse_float(seconds, "decision_seconds"),
        )


class OutcomeKind(StrEnum):
    """How a duel ended: a winner and a loser, neither preferred, or not judged (failed);
    or ``retracted``: the answer given to the duel is taken back (a person's undo)."""

    DECISIVE = "decisive"
    INDIFFERENT = "indifferent"
    FAILED = "failed"
    RETRACTED = "retracted"


@dataclass(frozen=True)
class DuelOutcome(_StatusRecord):
    """The oracle's answer to a duel request (oracle → optimizer).

    Keys: ``run_id``, ``duel_id``, ``first_id``, ``second_id`` (echo the request), ``kind``
    (``decisive``|``indifferent``|``failed``|``retracted``); ``winner_id`` and ``loser_id`` iff
    decisive (a permutation of first/second); ``reason`` (non-empty text) iff failed; optional
    ``answer_seconds`` (finite float >= 0, never when failed or retracted): how long a person
    took from seeing the duel to answering it (set by ``judge_node``; absent for the simulated
    oracle); optional ``judge`` (the answering person's name) and ``note`` (their words on the
    duel), non-empty text, only on a person's decisive or indifferent answer.

    ``retracted`` (only ``judge_node``, a person's undo) takes back the answer given to duel
    ``duel_id``: the optimizer returns to its state before that answer and requests the duel
    again under the same id; duels it requested after that answer are withdrawn (their ids
    are never reused). A retraction it cannot honour is counted (``retraction_refused``).
    """

    STATUS_NAME = DUEL_OUTCOME_NAME
    SCHEMA = "duel_outcome"

    run_id: str
    duel_id: int
    first_id: int
    second_id: int
    kind: OutcomeKind
    winner_id: int | None = None
    loser_id: int | None = None
    reason: str = ""
    answer_seconds: float | None = None
    judge: str = ""
    note: str = ""

    def __post_init__(self) -> None:
        _check_duel(self)
        object.__setattr__(self, "kind", _enum(OutcomeKind, self.kind, "kind"))
        if self.answer_seconds is not None:
            seconds = check_finite(self.answer_seconds, "answer_seconds")
            if seconds < 0.0:
                raise FieldError(
                    "answer_seconds", R.OUT_OF_BOUNDS, f"must be >= 0, got {seconds!r}"
                )
            _require(
                self.kind not in (OutcomeKind.FAILED, OutcomeKind.RETRACTED),
                "answer_seconds",
                f"must be absent when {self.kind}",
            )
            object.__setattr__(self, "answer_seconds", seconds)
        if self.kind is OutcomeKind.DECISIVE:
            _require(
                self.winner_id is not None and self.loser_id is not None,
                "winner_id",
                "winner_id and loser_id required when decisive",
            )
            check_id(self.winner_id, "winner_id")
            check_id(self.loser_id, "loser_id")
            _require(
                {self.winner_id, self.loser_id} == {self.first_id, self.second_id},
                "winner_id",
                f"winner {self.winner_id}/loser {self.loser_id} are not the duel's ids "
                f"{self.first_id}, {self.second_id}",
            )
        else:
            _require(
                self.winner_id is None and self.loser_id is None,
                "winner_id",
                f"winner_id/loser_id must be absent when {self.kind}",
            )
        if self.kind is OutcomeKind.FAILED:
            check_text(self.reason, "reason", allow_empty=False)
        else:
            _require(not self.reason, "reason", f"must be empty when {self.kind}")
        for name in ("judge", "note"):
            text = check_text(getattr(self, name), name)
            _require(
                not text or self.kind in (OutcomeKind.DECISIVE, OutcomeKind.INDIFFERENT),
                name,
                f"must be empty when {self.kind}",
            )

    @classmethod
    def decisive(
        cls,
        request: DuelRequest,
        winner_id: int,
        *,
        answer_seconds: float | None = None,
        judge: str = "",
        note: str = "",
    ) -> DuelOutcome:
        """``winner_id`` beat the other candidate of ``request``."""
        loser = request.second_id if winner_id == request.first_id else request.first_id
        return cls(
            request.run_id,
            request.duel_id,
            request.first_id,
            request.second_id,
            OutcomeKind.DECISIVE,
            winner_id,
            loser,
            answer_seconds=answer_seconds,
            judge=judge,
            note=note,
        )

    @classmethod
    def indifferent(
        cls,
        request: DuelRequest,
        *,
        answer_seconds: float | None = None,
        judge: str = "",
        note: str = "",
    ) -> DuelOutcome:
        """Neither candidate of ``request`` was preferred."""
        return cls(
            request.run_id,
            request.duel_id,
            request.first_id,
            request.second_id,
            OutcomeKind.INDIFFERENT,
            answer_seconds=answer_seconds,
            judge=judge,
            note=note,
        )

    @classmethod
    def retracted(cls, request: DuelRequest) -> DuelOutcome:
        """The answer given to ``request``'s duel is taken back."""
        return cls(
            request.run_id,
            request.duel_id,
            request.first_id,
            request.second_id,
            OutcomeKind.RETRACTED,
        )

    @classmethod
    def failed(cls, request: DuelRequest, reason: str) -> DuelOutcome:
        """The duel could not be judged (missing episode, failed episode, timeout, ...)."""
        return cls(
            request.run_id,
            request.duel_id,
            request.first_id,
            request.second_id,
            OutcomeKind.FAILED,
            reason=reason,
        )

    def encode(self) -> DiagnosticStatus:
        """The ROS message."""
        values = {**_duel_values(self), "kind": self.kind.value}
        level = LEVEL_OK
        if self.kind is OutcomeKind.DECISIVE:
            values["winner_id"] = str(self.winner_id)
            values["loser_id"] = str(self.loser_id)
        elif self.kind is OutcomeKind.FAILED:
            values["reason"] = self.reason
            level = LEVEL_ERROR
        if self.answer_seconds is not None:
            values["answer_seconds"] = format_float(self.answer_seconds)
        for name in ("judge", "note"):
            if getattr(self, name):
                values[name] = getattr(self, name)
        return make_status(DUEL_OUTCOME_NAME, level, self.reason, values)

    @classmethod
    def _from_status(
        cls, level: int, v: dict[str, str], expected_run_id: str | None
    ) -> DuelOutcome:
        base = ("run_id", "duel_id", "first_id", "second_id", "kind")
        require_keys(
            v, base, ("winner_id", "loser_id", "reason", "answer_seconds", "judge", "note")
        )
        seconds = (
            parse_float(v["answer_seconds"], "answer_seconds") if "answer_seconds" in v else None
        )
        timed: tuple[str, ...] = ("answer_seconds",) if seconds is not None else ()
        timed += tuple(name for name in ("judge", "note") if name in v)
        judge, note = v.get("judge", ""), v.get("note", "")
        run_id = check_run_id(v["run_id"])
        check_expected_run(run_id, expected_run_id)
        duel_id = parse_id(v["duel_id"], "duel_id")
        first = parse_id(v["first_id"], "first_id")
        second = parse_id(v["second_id"], "second_id")
        kind = _enum(OutcomeKind, v["kind"], "kind")
        if kind in (OutcomeKind.DECISIVE, OutcomeKind.INDIFFERENT):
            decisive = kind is OutcomeKind.DECISIVE
            ids = ("winner_id", "loser_id") if decisive else ()
            require_keys(v, (*base, *ids, *timed), context=f" (must be absent when kind is {kind})")
            _check_level(level, LEVEL_OK)
            return cls(
                run_id,
                duel_id,
                first,
                second,
                kind,
                parse_id(v["winner_id"], "winner_id") if decisive else None,
                parse_id(v["loser_id"], "loser_id") if decisive else None,
                answer_seconds=seconds,
                judge=judge,
                note=note,
            )
        if kind is OutcomeKind.RETRACTED:
            require_keys(v, base, context=" (must be absent when kind is retracted)")
            _check_level(level, LEVEL_OK)
            return cls(run_id, duel_id, first, second, OutcomeKind.RETRACTED)
        require_keys(v, (*base, "reason"), context=" (must be absent when kind is failed)")
        _check_level(level, LEVEL_ERROR)
        return cls(run_id, duel_id, first, second, OutcomeKind.FAILED, reason=v["reason"])
