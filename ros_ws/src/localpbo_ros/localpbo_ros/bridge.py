"""The plain-Python logic of ``param_bridge_node`` (no ROS here): which target parameter each
space parameter sets, whether the target's parameters can take the space, and a trial's score.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from localpbo_core.space import ParameterSpace
from localpbo_core.validation import SettingError

SCORE_KINDS = ("reward", "cost")
REDUCERS = ("mean", "sum", "last", "min", "max")


def target_names(space: ParameterSpace, mapping: Mapping[str, Any]) -> tuple[str, ...]:
    """The target's parameter name for each space parameter (identity unless mapped).

    Raises:
        SettingError: ``mapping.<key>`` for a key that is not a space parameter or a value
            that is not a parameter name; ``mapping`` when two map to the same target.
    """
    for key, value in mapping.items():
        if key not in space.names:
            raise SettingError(
                f"mapping.{key}", f"is not a parameter of the space ({', '.join(space.names)})"
            )
        if not isinstance(value, str) or not value:
            raise SettingError(f"mapping.{key}", f"must be a parameter name, got {value!r}")
    names = tuple(str(mapping.get(n, n)) for n in space.names)
    if len(set(names)) != len(names):
        raise SettingError("mapping", f"two space parameters set the same target: {names}")
    return names


@dataclass(frozen=True)
class TargetParameter:
    """What the target node says about one of its parameters (parameter services)."""

    name: str
    exists: bool
    is_double: bool = False
    read_only: bool = False
    ranges: tuple[tuple[float, float], ...] = ()


def check_target(
    space: ParameterSpace, names: tuple[str, ...], described: Mapping[str, TargetParameter]
) -> None:
    """Refuse a target that cannot take every candidate of ``space``.

    Each target parameter must exist, be a double, be writable and (when its descriptor has
    a ``floating_point_range``) contain the space's bounds.

    Raises:
        SettingError: ``target.<target parameter>`` with the reason (space parameter named).
    """
    for p, name in zip(space.parameters, names, strict=True):
        field = f"target.{name}"
        info = described.get(name)
        via = "" if name == p.name else f" (space parameter {p.name!r})"
        if info is None or not info.exists:
            raise SettingError(field, f"the target node has no parameter {name!r}{via}")
        if not info.is_double:
            raise SettingError(field, f"is not a double parameter{via}")
        if info.read_only:
            raise SettingError(field, f"is read-only{via}")
        for lo, hi in info.ranges:
            if not lo <= p.lower <= p.upper <= hi:
                raise SettingError(
                    field,
                    f"accepts [{lo!r}, {hi!r}], the space asks for [{p.lower!r}, {p.upper!r}]{via}",
                )


class ScoreWindow:
    """Score samples of one trial, reduced to one value (a cost is negated: higher is better).

    Args:
        kind: ``reward`` (higher is better) or ``cost`` (lower is better).
        reduce: ``mean``, ``sum``, ``last``, ``min`` or ``max`` of the samples (of the raw
            samples, before a cost is negated).
    """

    def __init__(self, kind: str, reduce: str) -> None:
        if kind not in SCORE_KINDS:
            raise SettingError("score_kind", f"must be one of {SCORE_KINDS}, got {kind!r}")
        if reduce not in REDUCERS:
            raise SettingError("score_reduce", f"must be one of {REDUCERS}, got {reduce!r}")
        self.kind = kind
        self.reduce = reduce
        self.open = False
        self._clear()

    def _clear(self) -> None:
        self.count = 0
        self._sum = 0.0
        self._last = 0.0
        self._min = math.inf
        self._max = -math.inf

    def start(self) -> None:
        """Open the window (forgetting earlier samples)."""
        self._clear()
        self.open = True

    def add(self, value: float) -> bool:
        """Take a sample; False (and nothing taken) when closed or not finite."""
        if not self.open or not math.isfinite(value):
            return False
        self.count += 1
        self._sum += value
        self._last = value
        self._min = min(self._min, value)
        self._max = max(self._max, value)
        return True

    def close(self) -> float | None:
        """Close the window; the trial's score (None without samples or if not finite)."""
        self.open = False
        if not self.count:
            return None
        value = {
            "mean": self._sum / self.count,
            "sum": self._sum,
            "last": self._last,
            "min": self._min,
            "max": self._max,
        }[self.reduce]
        score = -value if self.kind == "cost" else value
        return score if math.isfinite(score) else None
