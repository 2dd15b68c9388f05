"""Decode errors and the result type returned by every codec's ``decode``.

Decoders run inside ROS subscription callbacks, so they never raise: a message that fails
validation yields a :class:`DecodeError` that names the schema, the field, the reason (a
:class:`DecodeReason`, for counting) and the problem (text, for people). Encoders, which run on
the sender's own data, raise :class:`FieldError` (a :class:`ValueError`) instead.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import StrEnum
from typing import TypeAlias, TypeVar

T = TypeVar("T")


class DecodeReason(StrEnum):
    """Why a message (or a value given to an encoder) was refused.

    The values are lower-case identifiers, so nodes use them as counter names
    (``dropped_<reason>``).
    """

    WRONG_TYPE = "wrong_type"
    """A value of the wrong type: a ROS message that is not of the schema's class, a JSON
    list where an object is required, a string where a number is required."""
    MALFORMED = "malformed"
    """Unreadable structure: missing, unexpected or repeated key; text that is not an id, a
    number or JSON; wrong schema name, kind or label grammar; undecodable message."""
    WRONG_RUN = "wrong_run"
    """A valid run id other than the expected one."""
    WRONG_SHAPE = "wrong_shape"
    """A vector that is empty or whose length is not the run's dimension."""
    NON_FINITE = "non_finite"
    """NaN or infinity where a finite number is required."""
    OUT_OF_BOUNDS = "out_of_bounds"
    """A number outside its range: θ outside the task box, an id or count out of range."""
    TOO_LARGE = "too_large"
    """Over a size cap: vector length, text length, number of keys, JSON bytes."""
    INCONSISTENT = "inconsistent"
    """Fields that contradict each other: a self-duel, a winner that is not one of the duel's
    candidates, a level that does not match the status, a layout size that is not the data's."""


@dataclass(frozen=True)
class DecodeError:
    """Why a received message was rejected.

    Attributes:
        schema: the suite schema the message was decoded as, e.g. ``"candidate"``.
        field: the offending field (a KeyValue key, ``layout.dim[0].label``, ``data[3]``, ...).
        reason: the kind of problem, for counting.
        problem: a human-readable description of what is wrong.
    """

    schema: str
    field: str
    reason: DecodeReason
    problem: str

    def __str__(self) -> str:
        return f"{self.schema}: {self.field}: {self.problem}"


Result: TypeAlias = T | DecodeError
"""``decode`` returns either the decoded value or a :class:`DecodeError` (``Result[T]``)."""


class FieldError(ValueError):
    """A validation failure tied to one field; decoders turn it into a :class:`DecodeError`.

    Attributes:
        field: the offending field.
        reason: the kind of problem.
        problem: a human-readable description.
    """

    def __init__(self, field: str, reason: DecodeReason, problem: str) -> None:
        super().__init__(f"{field}: {problem}")
        self.field = field
        self.reason = reason
        self.problem = problem


def is_error(result: object) -> bool:
    """True when ``result`` is a :class:`DecodeError`."""
    return isinstance(result, DecodeError)
