"""Decode errors and the result type returned by every codec's ``decode``.

Decoders run inside ROS subscription callbacks, so they never raise: a message that fails
validation yields a :class:`DecodeError` that names the schema, the field and the problem.
Encoders, which run on the sender's own data, raise :class:`ValueError` instead.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TypeVar

T = TypeVar("T")


@dataclass(frozen=True)
class DecodeError:
    """Why a received message was rejected.

    Attributes:
        schema: the suite schema the message was decoded as, e.g. ``"candidate"``.
        field: the offending field (a KeyValue key, ``layout.dim[0].label``, ``data[3]``, ...).
        problem: a human-readable description of what is wrong.
    """

    schema: str
    field: str
    problem: str

    def __str__(self) -> str:
        return f"{self.schema}: {self.field}: {self.problem}"


Result = T | DecodeError
"""``decode`` returns either the decoded value or a :class:`DecodeError`."""


class FieldError(ValueError):
    """A validation failure tied to one field; decoders turn it into a :class:`DecodeError`."""

    def __init__(self, field: str, problem: str) -> None:
        super().__init__(f"{field}: {problem}")
        self.field = field
        self.problem = problem


def is_error(result: object) -> bool:
    """True when ``result`` is a :class:`DecodeError`."""
    return isinstance(result, DecodeError)
