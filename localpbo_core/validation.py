"""Checks of user-supplied settings, shared by the optimizers and the problems.

Every helper takes the field name first, returns the value in its canonical type and raises
:class:`SettingError` naming the field. The reason is data (``err.field``, ``err.reason``);
``str(err)`` is ``"field: reason"``. Each check has one wording:

* :func:`check_int`: ``"must be an integer >= {minimum}, got {value!r}"``;
* :func:`check_float`: ``"must be a finite number, got {value!r}"`` or
  ``"must lie in {interval}, got {value!r}"`` (``[0, inf)``, ``(0, 1]``, ...);
* :func:`check_choice`: ``"must be one of {choices}, got {value!r}"``;
* :func:`check_theta`: ``"must be a numeric vector ({why})"``,
  ``"expected shape ({dim},), got {shape}"``, ``"contains NaN or inf"`` or
  ``"must lie in [0, 1]^{dim}"``.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np


class ValidationError(ValueError):
    """A value was rejected. ``field`` names it and ``reason`` says why; ``str()`` is
    ``"field: reason"``. Base of :class:`SettingError` and the optimizers' ``InvalidOutcome``.
    """

    def __init__(self, field: str, reason: str) -> None:
        super().__init__(field, reason)  # both in args: the error pickles and unpickles
        self.field = field
        self.reason = reason

    def __str__(self) -> str:
        return f"{self.field}: {self.reason}"


class SettingError(ValidationError):
    """A setting (an option, a seed, a parameter vector) was rejected.

    ``field`` is a dotted path for nested settings, e.g. ``optimizer_options.batch_size``.
    """

    def within(self, prefix: str) -> SettingError:
        """The same error with ``prefix.`` in front of its field."""
        return SettingError(f"{prefix}.{self.field}", self.reason)


def check_int(field: str, value: object, minimum: int = 1) -> int:
    """``value`` as an int if it is an integer (Python or numpy, not a bool) ``>= minimum``."""
    if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < minimum:
        raise SettingError(field, f"must be an integer >= {minimum}, got {value!r}")
    return int(value)


def _interval(
    minimum: float | None, maximum: float | None, minimum_open: bool, maximum_open: bool
) -> str:
    lo = "(-inf" if minimum is None else f"{'(' if minimum_open else '['}{minimum:g}"
    hi = "inf)" if maximum is None else f"{maximum:g}{')' if maximum_open else ']'}"
    return f"{lo}, {hi}"


def check_float(
    field: str,
    value: object,
    *,
    minimum: float | None = None,
    maximum: float | None = None,
    minimum_open: bool = False,
    maximum_open: bool = False,
) -> float:
    """``value`` as a finite float within the bounds (None: unbounded on that side; a bound
    is included unless ``minimum_open``/``maximum_open``). Python and numpy ints and floats
    are accepted, bools are not."""
    if isinstance(value, bool) or not isinstance(value, int | float | np.integer | np.floating):
        raise SettingError(field, f"must be a finite number, got {value!r}")
    v = float(value)
    if not np.isfinite(v):
        raise SettingError(field, f"must be a finite number, got {value!r}")
    below = minimum is not None and (v <= minimum if minimum_open else v < minimum)
    above = maximum is not None and (v >= maximum if maximum_open else v > maximum)
    if below or above:
        interval = _interval(minimum, maximum, minimum_open, maximum_open)
        raise SettingError(field, f"must lie in {interval}, got {value!r}")
    return v


def check_choice(field: str, value: object, choices: Sequence[str]) -> str:
    """``value`` if it is one of ``choices``."""
    if not isinstance(value, str) or value not in choices:
        raise SettingError(field, f"must be one of {tuple(choices)}, got {value!r}")
    return value


def check_theta(field: str, theta: object, dim: int) -> np.ndarray:
    """``theta`` as a new read-only float64 vector of shape ``(dim,)`` in ``[0, 1]^dim``
    (the normalised parameters every optimizer and problem works on)."""
    try:
        arr = np.array(theta, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise SettingError(field, f"must be a numeric vector ({exc})") from exc
    if arr.shape != (dim,):
        raise SettingError(field, f"expected shape ({dim},), got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise SettingError(field, "contains NaN or inf")
    if np.any(arr < 0.0) or np.any(arr > 1.0):
        raise SettingError(field, f"must lie in [0, 1]^{dim}")
    arr.setflags(write=False)
    return arr
