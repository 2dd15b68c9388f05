"""Field validators shared by the codecs (run ids, integer ids, floats, KeyValue lists).

Every validator raises :class:`~localpbo_msgs_py.errors.FieldError` naming the field, so one
code path serves both encoders (which let it propagate as a ``ValueError``) and decoders (which
turn it into a :class:`~localpbo_msgs_py.errors.DecodeError`).
"""

from __future__ import annotations

import array
import math
import re
from collections.abc import Iterable, Mapping, Sequence

import numpy as np

from localpbo_msgs_py.errors import FieldError

RUN_ID_PATTERN = re.compile(r"[A-Za-z0-9][A-Za-z0-9_.-]{0,63}")
"""Run ids: 1–64 characters, ASCII letters/digits then letters/digits/``_.-``."""

ID_PATTERN = re.compile(r"0|[1-9][0-9]{0,18}")
"""Candidate/duel ids on the wire: a non-negative decimal integer without sign or leading 0."""

MAX_ID = 2**63 - 1
"""Largest id (fits ``int64``/``uint64`` in C++)."""

MAX_THETA_LEN = 65536
"""Default cap on the length of a θ vector a decoder accepts."""

MAX_KEYVALUES = 64
"""Cap on the number of KeyValue pairs in one DiagnosticStatus."""

MAX_TEXT = 4096
"""Cap on the length of any one string field (KeyValue value, status message, label)."""

KEY_PATTERN = re.compile(r"[a-z][a-z0-9_.]{0,63}")
"""Allowed KeyValue keys and counter names."""


def check_run_id(value: object, field: str = "run_id") -> str:
    """Return ``value`` if it is a valid run id, else raise ``FieldError``."""
    if not isinstance(value, str):
        raise FieldError(field, f"must be a string, got {type(value).__name__}")
    if RUN_ID_PATTERN.fullmatch(value) is None:
        raise FieldError(
            field, f"{value[:80]!r} is not a run id ([A-Za-z0-9][A-Za-z0-9_.-]{{0,63}})"
        )
    return value


def check_expected_run(run_id: str, expected: str | None, field: str = "run_id") -> None:
    """Raise ``FieldError`` when ``expected`` is given and differs from ``run_id``."""
    if expected is not None and run_id != expected:
        raise FieldError(field, f"wrong run: got {run_id!r}, expected {expected!r}")


def check_id(value: object, field: str) -> int:
    """Return ``value`` if it is an integer id in ``[0, 2**63 - 1]`` (bools refused)."""
    if isinstance(value, bool) or not isinstance(value, int):
        raise FieldError(field, f"must be an integer id, got {type(value).__name__}")
    if value < 0:
        raise FieldError(field, f"must be non-negative, got {value}")
    if value > MAX_ID:
        raise FieldError(field, f"must be at most 2**63-1, got {value}")
    return value


def parse_id(text: str, field: str) -> int:
    """Parse a wire id (decimal, no sign, no leading zeros, no spaces)."""
    if ID_PATTERN.fullmatch(text) is None:
        raise FieldError(field, f"{text[:80]!r} is not a non-negative integer id")
    return check_id(int(text), field)


def check_finite(value: object, field: str) -> float:
    """Return ``value`` as float if it is a finite real number (bools refused)."""
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise FieldError(field, f"must be a number, got {type(value).__name__}")
    out = float(value)
    if not math.isfinite(out):
        raise FieldError(field, f"must be finite, got {out!r}")
    return out


def parse_float(text: str, field: str) -> float:
    """Parse a finite float written by ``repr`` (Python) or ``%.17g``/``to_chars`` (C++)."""
    try:
        out = float(text)
    except ValueError:
        raise FieldError(field, f"{text[:80]!r} is not a number") from None
    if not math.isfinite(out):
        raise FieldError(field, f"must be finite, got {text[:80]!r}")
    return out


def check_text(value: object, field: str, *, allow_empty: bool = True) -> str:
    """Return ``value`` if it is a string of at most ``MAX_TEXT`` characters."""
    if not isinstance(value, str):
        raise FieldError(field, f"must be a string, got {type(value).__name__}")
    if len(value) > MAX_TEXT:
        raise FieldError(field, f"longer than {MAX_TEXT} characters ({len(value)})")
    if not allow_empty and not value:
        raise FieldError(field, "must not be empty")
    return value


def _fast_floats(seq: object) -> tuple[float, ...] | None:
    """Floats of a float64 ``array.array``/ndarray (rclpy's ``data`` fields), else None."""
    if isinstance(seq, array.array) and seq.typecode == "d":
        return tuple(seq)
    if isinstance(seq, np.ndarray) and seq.dtype == np.float64 and seq.ndim == 1:
        return tuple(seq.tolist())
    if isinstance(seq, tuple | list) and all(type(v) is float for v in seq):
        return tuple(seq)
    return None


def check_vector(
    values: Iterable[object],
    field: str,
    *,
    expected_len: int | None = None,
    lower: Sequence[float] | None = None,
    upper: Sequence[float] | None = None,
    max_len: int = MAX_THETA_LEN,
) -> tuple[float, ...]:
    """Validate a θ vector: length, finiteness and (optionally) the box ``[lower, upper]``."""
    seq = values if isinstance(values, Sequence) else list(values)
    n = len(seq)
    if n > max_len:
        raise FieldError(field, f"has {n} entries, more than the cap {max_len}")
    if n == 0:
        raise FieldError(field, "is empty")
    if expected_len is not None and n != expected_len:
        raise FieldError(field, f"has length {n}, expected {expected_len}")
    out = _fast_floats(seq)
    if out is None:
        out = tuple(check_finite(v, f"{field}[{i}]") for i, v in enumerate(seq))
    else:
        finite = np.isfinite(np.asarray(out))
        if not finite.all():
            i = int(np.argmin(finite))
            raise FieldError(f"{field}[{i}]", f"must be finite, got {out[i]!r}")
    if lower is not None or upper is not None:
        for name, bound in (("lower", lower), ("upper", upper)):
            if bound is not None and len(bound) != n:
                raise FieldError(field, f"{name} bound has length {len(bound)}, θ has {n}")
        for i, v in enumerate(out):
            if lower is not None and v < lower[i]:
                raise FieldError(f"{field}[{i}]", f"{v!r} is below the lower bound {lower[i]!r}")
            if upper is not None and v > upper[i]:
                raise FieldError(f"{field}[{i}]", f"{v!r} is above the upper bound {upper[i]!r}")
    return out


def format_float(value: float) -> str:
    """Shortest text that parses back to exactly ``value`` (``repr``)."""
    return repr(float(value))


def keyvalues_to_dict(pairs: Sequence[object], field: str = "values") -> dict[str, str]:
    """Turn a ``diagnostic_msgs/KeyValue[]`` into a dict, refusing duplicates and oversize."""
    if len(pairs) > MAX_KEYVALUES:
        raise FieldError(field, f"has {len(pairs)} entries, more than the cap {MAX_KEYVALUES}")
    out: dict[str, str] = {}
    for i, kv in enumerate(pairs):
        key = getattr(kv, "key", None)
        value = getattr(kv, "value", None)
        if not isinstance(key, str) or not isinstance(value, str):
            raise FieldError(f"{field}[{i}]", "is not a diagnostic_msgs/KeyValue")
        if key in out:
            raise FieldError(key, "appears more than once")
        check_text(value, key)
        out[key] = value
    return out


def require_keys(
    values: Mapping[str, str],
    required: Iterable[str],
    optional: Iterable[str] = (),
    context: str = "",
) -> None:
    """Raise ``FieldError`` for the first missing required key or unexpected key."""
    req = list(required)
    allowed = set(req) | set(optional)
    for key in req:
        if key not in values:
            raise FieldError(key, "missing")
    for key in values:
        if key not in allowed:
            raise FieldError(key, f"unexpected key{context}")
