"""Field validators shared by the codecs (run ids, integer ids, floats, KeyValue lists).

Every validator raises :class:`~localpbo_msgs_py.errors.FieldError` naming the field and the
reason, so one code path serves both encoders (which let it propagate as a ``ValueError``) and
decoders (which turn it into a :class:`~localpbo_msgs_py.errors.DecodeError`). Each check has
one function here and so one wording, whichever codec runs it.
"""

from __future__ import annotations

import array
import math
import re
from collections.abc import Iterable, Mapping, Sequence
from typing import Any

import numpy as np

from localpbo_msgs_py.errors import DecodeReason, FieldError

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

R = DecodeReason


def check_cap(size: int, cap: int, field: str, unit: str) -> None:
    """Raise ``FieldError`` (``TOO_LARGE``) when ``size`` ``unit`` exceed ``cap``."""
    if size > cap:
        raise FieldError(field, R.TOO_LARGE, f"has {size} {unit}, more than the cap {cap}")


def missing_key(field: str, key: str) -> FieldError:
    """The error for a required key that is absent (``field`` holds the keys)."""
    return FieldError(field, R.MALFORMED, f"missing key {key!r}")


def unexpected_key(field: str, key: str, context: str = "") -> FieldError:
    """The error for a key the schema does not allow."""
    return FieldError(field, R.MALFORMED, f"unexpected key {key!r}{context}")


def repeated_key(field: str, key: str) -> FieldError:
    """The error for a key given more than once."""
    return FieldError(field, R.MALFORMED, f"key {key!r} appears more than once")


def wrong_type(field: str, expected: str, value: object) -> FieldError:
    """The error for a value of the wrong Python or ROS type."""
    return FieldError(field, R.WRONG_TYPE, f"expected {expected}, got {type(value).__name__}")


def check_run_id(value: object, field: str = "run_id") -> str:
    """Return ``value`` if it is a valid run id, else raise ``FieldError``."""
    text = check_text(value, field)
    if RUN_ID_PATTERN.fullmatch(text) is None:
        raise FieldError(
            field,
            R.MALFORMED,
            f"{text[:80]!r} is not a run id ([A-Za-z0-9][A-Za-z0-9_.-]{{0,63}})",
        )
    return text


def check_expected_run(run_id: str, expected: str | None, field: str = "run_id") -> None:
    """Raise ``FieldError`` (``WRONG_RUN``) when ``expected`` is given and differs."""
    if expected is not None and run_id != expected:
        raise FieldError(field, R.WRONG_RUN, f"wrong run: got {run_id!r}, expected {expected!r}")


def check_id(value: object, field: str) -> int:
    """Return ``value`` if it is an integer id in ``[0, 2**63 - 1]`` (bools refused)."""
    if isinstance(value, bool) or not isinstance(value, int):
        raise wrong_type(field, "an integer id", value)
    if value < 0:
        raise FieldError(field, R.OUT_OF_BOUNDS, f"must be non-negative, got {value}")
    if value > MAX_ID:
        raise FieldError(field, R.OUT_OF_BOUNDS, f"must be at most 2**63-1, got {value}")
    return value


def check_minimum(value: object, field: str, minimum: int) -> int:
    """Return ``value`` if it is an integer id of at least ``minimum``."""
    out = check_id(value, field)
    if out < minimum:
        raise FieldError(field, R.OUT_OF_BOUNDS, f"must be >= {minimum}, got {out}")
    return out


def parse_id(text: str, field: str) -> int:
    """Parse a wire id (decimal, no sign, no leading zeros, no spaces)."""
    if ID_PATTERN.fullmatch(text) is None:
        raise FieldError(field, R.MALFORMED, f"{text[:80]!r} is not a non-negative integer id")
    return check_id(int(text), field)


def _not_finite(field: str, value: float) -> FieldError:
    return FieldError(field, R.NON_FINITE, f"must be finite, got {value!r}")


def check_finite(value: object, field: str) -> float:
    """Return ``value`` as float if it is a finite real number (bools refused)."""
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise wrong_type(field, "a number", value)
    out = float(value)
    if not math.isfinite(out):
        raise _not_finite(field, out)
    return out


def parse_float(text: str, field: str) -> float:
    """Parse a finite float written by ``repr`` (Python) or ``%.17g``/``to_chars`` (C++)."""
    try:
        out = float(text)
    except ValueError:
        raise FieldError(field, R.MALFORMED, f"{text[:80]!r} is not a number") from None
    return check_finite(out, field)


def check_text(value: object, field: str, *, allow_empty: bool = True) -> str:
    """Return ``value`` if it is a string of at most ``MAX_TEXT`` characters."""
    if not isinstance(value, str):
        raise wrong_type(field, "a string", value)
    check_cap(len(value), MAX_TEXT, field, "characters")
    if not allow_empty and not value:
        raise FieldError(field, R.MALFORMED, "must not be empty")
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
    check_cap(n, max_len, field, "entries")
    if n == 0:
        raise FieldError(field, R.WRONG_SHAPE, "is empty")
    if expected_len is not None and n != expected_len:
        raise FieldError(field, R.WRONG_SHAPE, f"has length {n}, expected {expected_len}")
    out = _fast_floats(seq)
    if out is None:
        out = tuple(check_finite(v, f"{field}[{i}]") for i, v in enumerate(seq))
    else:
        finite = np.isfinite(np.asarray(out))
        if not finite.all():
            i = int(np.argmin(finite))
            raise _not_finite(f"{field}[{i}]", out[i])
    if lower is not None or upper is not None:
        for name, bound in (("lower", lower), ("upper", upper)):
            if bound is not None and len(bound) != n:
                raise FieldError(
                    field, R.WRONG_SHAPE, f"{name} bound has length {len(bound)}, θ has {n}"
                )
        for i, v in enumerate(out):
            if lower is not None and v < lower[i]:
                raise FieldError(
                    f"{field}[{i}]", R.OUT_OF_BOUNDS, f"{v!r} is below the lower bound {lower[i]!r}"
                )
            if upper is not None and v > upper[i]:
                raise FieldError(
                    f"{field}[{i}]", R.OUT_OF_BOUNDS, f"{v!r} is above the upper bound {upper[i]!r}"
                )
    return out


def format_float(value: float) -> str:
    """Shortest text that parses back to exactly ``value`` (``repr``)."""
    return repr(float(value))


def keyvalues_to_dict(pairs: Sequence[object], field: str = "values") -> dict[str, str]:
    """Turn a ``diagnostic_msgs/KeyValue[]`` into a dict, refusing duplicates and oversize."""
    check_cap(len(pairs), MAX_KEYVALUES, field, "entries")
    out: dict[str, str] = {}
    for i, kv in enumerate(pairs):
        key = getattr(kv, "key", None)
        value = getattr(kv, "value", None)
        if not isinstance(key, str) or not isinstance(value, str):
            raise wrong_type(f"{field}[{i}]", "diagnostic_msgs/KeyValue", kv)
        if key in out:
            raise repeated_key(key, key)
        check_text(value, key)
        out[key] = value
    return out


def require_keys(
    values: Mapping[str, Any],
    required: Iterable[str],
    optional: Iterable[str] | None = (),
    context: str = "",
    *,
    field: str | None = None,
) -> None:
    """Raise ``FieldError`` for the first missing required key or unexpected key.

    ``optional=None`` allows any further key. The error names ``field`` when given (keys
    inside one field, like a layout label), else the key itself.
    """
    req = list(required)
    for key in req:
        if key not in values:
            raise missing_key(field or key, key)
    if optional is None:
        return
    allowed = set(req) | set(optional)
    for key in values:
        if key not in allowed:
            raise unexpected_key(field or key, key, context)
