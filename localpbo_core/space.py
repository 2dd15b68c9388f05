"""Parameter spaces: tune the declared parameters of your own controller instead of a task.

A space file (YAML, or the same mapping as JSON) lists the parameters to tune::

    name: pid                     # optional; the file's stem by default
    value_range: 20.0             # optional: approximate spread of the trial scores; scales
                                  # the simulated oracle's noise (noise_fraction × value_range)
    goal: settles fast without overshoot   # optional: what "better" means, shown to a person
    parameters:
      - name: kp                  # the parameter (the target node's name unless mapped)
        lower: 0.1
        upper: 100.0
        log: true                 # optional: search log(kp) uniformly (bounds must be > 0)
        initial: 1.0              # optional: the current value, the optimizer's warm start
        unit: N/m                 # optional, for people and bags
        description: proportional gain

:class:`ParameterSpace` is problem-like (:class:`~localpbo_core.problems.Problem`): it maps θ
in [0,1]^d to the user's units (:meth:`ParameterSpace.to_native`; on a log scale
``exp(log lo + θ (log hi − log lo))``) and back (:meth:`ParameterSpace.from_native`), but it
has no evaluation of its own: the trials run on the user's system (``param_bridge_node``).
Every refusal is a :class:`~localpbo_core.validation.SettingError` whose field names the
parameter, e.g. ``space.kp.lower`` (``space.parameters[2].name`` while the name is unknown);
:func:`load_space` also names the file (``file pid.yaml: ...``).

Hostile files are refused before they cost time or memory: a file (or inline text) larger than
``MAX_SPACE_BYTES`` is refused before it is parsed; YAML anchors and aliases are refused (a
space needs none, and aliases are how a small file expands into gigabytes), as is nesting
deeper than ``MAX_DEPTH``; text that is not UTF-8, or YAML that is not a mapping, is reported
as such; values quoted in messages are shortened (:func:`shown`).
"""

from __future__ import annotations

import json
import math
import os
import re
import reprlib
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from localpbo_core.validation import SettingError, check_float, check_theta

__all__ = ["ParameterSpace", "SpaceParameter", "load_space", "parse_space"]

NAME_PATTERN = re.compile(r"[A-Za-z_][A-Za-z0-9_.]{0,99}")
"""Parameter names: ROS parameter names (dots allowed for nested ones)."""
SPACE_NAME_PATTERN = re.compile(r"[A-Za-z0-9][A-Za-z0-9_.-]{0,63}")
SPACE_KEYS = ("name", "value_range", "goal", "parameters")
PARAMETER_KEYS = ("name", "lower", "upper", "log", "initial", "unit", "description")
MAX_PARAMETERS = 1000
MAX_TEXT = 1000
MAX_SPACE_BYTES = 1 << 20
"""Largest space file or inline space text (1 MiB), checked before parsing; a run config
(itself at most 1 MiB) always fits, so a recorded space can be given back inline."""
MAX_DEPTH = 8
"""Deepest nesting of mappings and sequences a space file may have (a space needs 3)."""
TASK_PREFIX = "space:"
"""The task name of a space run in the run config: ``space:<name>``."""


@dataclass(frozen=True)
class SpaceParameter:
    """One tuned parameter: bounds in the user's units, scale, warm-start value, unit."""

    name: str
    lower: float
    upper: float
    log: bool = False
    initial: float | None = None
    unit: str = ""
    description: str = ""

    def to_dict(self) -> dict[str, Any]:
        """The file form (keys with default values left out)."""
        out: dict[str, Any] = {"name": self.name, "lower": self.lower, "upper": self.upper}
        if self.log:
            out["log"] = True
        if self.initial is not None:
            out["initial"] = self.initial
        if self.unit:
            out["unit"] = self.unit
        if self.description:
            out["description"] = self.description
        return out


@dataclass(frozen=True)
class ParameterSpace:
    """The box of a run over a user's parameters (see module docstring).

    Satisfies the ``Problem`` protocol except evaluation: :meth:`evaluate`,
    :meth:`evaluate_native` and :meth:`true_value` raise ``NotImplementedError``.
    """

    label: str
    parameters: tuple[SpaceParameter, ...]
    value_range: float = math.nan
    goal: str = ""
    """What "better" means, in one line, for a person judging trials (optional)."""

    @property
    def name(self) -> str:
        """The task name of the run: ``space:<label>``."""
        return TASK_PREFIX + self.label

    @property
    def dim(self) -> int:
        """Number of tuned parameters."""
        return len(self.parameters)

    @property
    def names(self) -> tuple[str, ...]:
        """Parameter names in θ order."""
        return tuple(p.name for p in self.parameters)

    @property
    def lower(self) -> tuple[float, ...]:
        """Lower bounds in the user's units."""
        return tuple(p.lower for p in self.parameters)

    @property
    def upper(self) -> tuple[float, ...]:
        """Upper bounds in the user's units."""
        return tuple(p.upper for p in self.parameters)

    def _arrays(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        log = np.array([p.log for p in self.parameters], dtype=bool)
        lo = np.array(self.lower, dtype=np.float64)
        hi = np.array(self.upper, dtype=np.float64)
        return log, lo, hi

    def to_native(self, theta: np.ndarray) -> np.ndarray:
        """θ in [0,1]^d → values in the user's units (log-scaled ones geometrically); the
        corners give the bounds exactly and rounding never leaves the box."""
        t = check_theta("theta", theta, self.dim)
        log, lo, hi = self._arrays()
        linear = lo + t * (hi - lo)
        with np.errstate(divide="ignore", invalid="ignore"):
            safe_lo = np.where(log, lo, 1.0)
            safe_hi = np.where(log, hi, 2.0)
            geometric = np.exp(np.log(safe_lo) + t * (np.log(safe_hi) - np.log(safe_lo)))
        native = np.where(log, geometric, linear)
        native = np.where(t == 0.0, lo, np.where(t == 1.0, hi, native))  # corners exact
        return np.clip(native, lo, hi)

    def from_native(self, x: Sequence[float] | np.ndarray) -> np.ndarray:
        """Values in the user's units → θ in [0,1]^d (the inverse of :meth:`to_native`).

        Raises:
            SettingError: ``x`` has the wrong length, is not finite or leaves the bounds.
        """
        arr = np.asarray(x, dtype=np.float64).reshape(-1)
        if arr.shape != (self.dim,):
            raise SettingError("x", f"expected {self.dim} values, got {arr.shape[0]}")
        log, lo, hi = self._arrays()
        for p, v in zip(self.parameters, arr, strict=True):
            if not (math.isfinite(v) and p.lower <= v <= p.upper):
                raise SettingError(p.name, f"{v!r} is outside [{p.lower!r}, {p.upper!r}]")
        with np.errstate(divide="ignore", invalid="ignore"):
            safe = np.where(log, arr, 1.0)
            safe_lo = np.where(log, lo, 1.0)
            safe_hi = np.where(log, hi, 2.0)
            geometric = (np.log(safe) - np.log(safe_lo)) / (np.log(safe_hi) - np.log(safe_lo))
        return np.clip(np.where(log, geometric, (arr - lo) / (hi - lo)), 0.0, 1.0)

    def warm_start(self) -> tuple[float, ...] | None:
        """θ of the ``initial`` values (the centre, in θ, for a parameter without one); None
        when no parameter has an initial value."""
        if all(p.initial is None for p in self.parameters):
            return None
        log, lo, hi = self._arrays()
        centre = np.where(log, np.sqrt(np.abs(lo * hi)), 0.5 * (lo + hi))
        x = [
            c if p.initial is None else p.initial
            for p, c in zip(self.parameters, centre, strict=True)
        ]
        return tuple(float(v) for v in self.from_native(x))

    def initial_native(self) -> tuple[float, ...] | None:
        """The warm start in the user's units (None without initial values)."""
        theta = self.warm_start()
        return None if theta is None else tuple(float(v) for v in self.to_native(np.asarray(theta)))

    def to_dict(self) -> dict[str, Any]:
        """The file form (JSON-serialisable; what the run config records)."""
        out: dict[str, Any] = {
            "name": self.label,
            "parameters": [p.to_dict() for p in self.parameters],
        }
        if math.isfinite(self.value_range):
            out["value_range"] = self.value_range
        if self.goal:
            out["goal"] = self.goal
        return out

    def evaluate(self, theta: np.ndarray, seed: int) -> float:
        """Not available: a space is evaluated by the user's system."""
        raise NotImplementedError(f"{self.name} is evaluated externally (param_bridge_node)")

    def evaluate_native(self, x: np.ndarray, seed: int) -> float:
        """Not available: a space is evaluated by the user's system."""
        raise NotImplementedError(f"{self.name} is evaluated externally (param_bridge_node)")

    def true_value(self, theta: np.ndarray) -> float:
        """Not available: a space is evaluated by the user's system."""
        raise NotImplementedError(f"{self.name} has no known true value")


_SHOWN = reprlib.Repr()
_SHOWN.maxlevel, _SHOWN.maxdict, _SHOWN.maxlist = 2, 4, 4
_SHOWN.maxstring = _SHOWN.maxother = 60


def shown(value: object) -> str:
    """``repr(value)`` cut to a few dozen characters (nested containers and long text
    abbreviated with ``...``), for quoting values of a file in messages."""
    return _SHOWN.repr(value)


def _unknown(field: str, obj: Mapping[str, Any], allowed: Sequence[str]) -> None:
    for key in obj:
        if key not in allowed:
            raise SettingError(
                f"{field}.{shown(key) if not isinstance(key, str) else key[:60]}",
                f"unknown key; allowed: {', '.join(allowed)}",
            )


def _text(field: str, value: object) -> str:
    if not isinstance(value, str) or len(value) > MAX_TEXT:
        size = f" ({len(value)} characters)" if isinstance(value, str) else ""
        raise SettingError(
            field, f"must be text of at most {MAX_TEXT} characters, got {shown(value)}{size}"
        )
    return value


def _float(field: str, value: object, **bounds: Any) -> float:
    """:func:`check_float` of a number (or numeric text); anything else refused here, so
    the message quotes it shortened."""
    value = _number(value)
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise SettingError(field, f"must be a finite number, got {shown(value)}")
    return check_float(field, value, **bounds)


def _number(value: object) -> object:
    """YAML 1.1 reads ``1e-3`` (no dot) as text: accept numeric text, refuse the rest later."""
    if isinstance(value, str) and len(value) <= 100:
        try:
            return float(value)
        except ValueError:
            return value
    return value


def _parameter(index: int, obj: object, seen: set[str]) -> SpaceParameter:
    where = f"space.parameters[{index}]"
    if not isinstance(obj, Mapping):
        raise SettingError(where, f"must be a mapping with name, lower, upper, got {shown(obj)}")
    name = obj.get("name")
    if not isinstance(name, str) or not NAME_PATTERN.fullmatch(name):
        raise SettingError(
            f"{where}.name", f"must be a parameter name like kp or gains.kp, got {shown(name)}"
        )
    if name in seen:
        raise SettingError(f"{where}.name", f"{name!r} is listed twice")
    seen.add(name)
    field = f"space.{name}"
    _unknown(field, obj, PARAMETER_KEYS)
    for key in ("lower", "upper"):
        if key not in obj:
            raise SettingError(f"{field}.{key}", "is required")
    lower = _float(f"{field}.lower", obj["lower"])
    upper = _float(f"{field}.upper", obj["upper"])
    if not lower < upper:
        raise SettingError(f"{field}.lower", f"must be below upper ({lower!r} >= {upper!r})")
    log = obj.get("log", False)
    if not isinstance(log, bool):
        raise SettingError(f"{field}.log", f"must be true or false, got {shown(log)}")
    if log and lower <= 0.0:
        raise SettingError(f"{field}.lower", f"must be > 0 on a log scale, got {lower!r}")
    initial = obj.get("initial")
    if initial is not None:
        initial = _float(f"{field}.initial", initial, minimum=lower, maximum=upper)
    return SpaceParameter(
        name,
        lower,
        upper,
        log,
        initial,
        _text(f"{field}.unit", obj.get("unit", "")),
        _text(f"{field}.description", obj.get("description", "")),
    )


def parse_space(obj: object, default_name: str = "space") -> ParameterSpace:
    """A validated space from its mapping form (a parsed file, or a run config's section).

    Raises:
        SettingError: naming the refused field (``space.kp.upper``, ``space.parameters``, …).
    """
    if not isinstance(obj, Mapping):
        raise SettingError("space", f"must be a mapping with a 'parameters' list, got {shown(obj)}")
    _unknown("space", obj, SPACE_KEYS)
    label = obj.get("name", default_name)
    if not isinstance(label, str) or not SPACE_NAME_PATTERN.fullmatch(label):
        raise SettingError(
            "space.name", f"must match [A-Za-z0-9][A-Za-z0-9_.-]*, got {shown(label)}"
        )
    value_range = math.nan
    if obj.get("value_range") is not None:
        value_range = _float(
            "space.value_range", obj["value_range"], minimum=0.0, minimum_open=True
        )
    params = obj.get("parameters")
    if not isinstance(params, list) or not params:
        raise SettingError("space.parameters", "must be a non-empty list of parameters")
    if len(params) > MAX_PARAMETERS:
        raise SettingError("space.parameters", f"at most {MAX_PARAMETERS} parameters")
    seen: set[str] = set()
    parsed = tuple(_parameter(i, p, seen) for i, p in enumerate(params))
    goal = _text("space.goal", obj.get("goal", ""))
    return ParameterSpace(label, parsed, value_range, goal)


def _stem_name(path: Path) -> str:
    stem = re.sub(r"[^A-Za-z0-9_.-]", "_", path.stem)[:64]
    return stem if SPACE_NAME_PATTERN.fullmatch(stem) else "space"


def _read_limited(path: Path) -> bytes:
    """At most ``MAX_SPACE_BYTES`` of ``path``; larger files are refused before reading them
    whole (also a device or pipe that never ends)."""
    try:
        with open(path, "rb") as stream:
            size = os.fstat(stream.fileno()).st_size
            if size > MAX_SPACE_BYTES:
                raise SettingError(
                    "space",
                    f"file {path}: is {size} bytes, more than the limit of {MAX_SPACE_BYTES} "
                    "bytes (1 MiB); a space file lists parameters and needs a few kB",
                )
            data = stream.read(MAX_SPACE_BYTES + 1)
    except OSError as exc:
        raise SettingError("space", f"file {path}: cannot read: {exc.strerror or exc}") from None
    if len(data) > MAX_SPACE_BYTES:
        raise SettingError(
            "space", f"file {path}: is more than the limit of {MAX_SPACE_BYTES} bytes (1 MiB)"
        )
    return data


def _parse_yaml(text: str, where: str) -> object:
    """YAML without anchors/aliases and nested at most ``MAX_DEPTH`` deep (checked on the
    event stream, which stops at the first offence), then loaded safely."""
    import yaml

    loader = getattr(yaml, "CSafeLoader", yaml.SafeLoader)
    depth = 0
    try:
        for event in yaml.parse(text, Loader=loader):
            if isinstance(event, yaml.AliasEvent) or getattr(event, "anchor", None) is not None:
                mark = event.start_mark
                raise SettingError(
                    "space",
                    f"{where}: uses a YAML anchor or alias (line {mark.line + 1}, column "
                    f"{mark.column + 1}); a space file must spell every value out",
                )
            if isinstance(event, yaml.CollectionStartEvent):
                depth += 1
                if depth > MAX_DEPTH:
                    raise SettingError(
                        "space",
                        f"{where}: is nested more than {MAX_DEPTH} levels deep (line "
                        f"{event.start_mark.line + 1})",
                    )
            elif isinstance(event, yaml.CollectionEndEvent):
                depth -= 1
        return yaml.load(text, Loader=loader)
    except yaml.YAMLError as exc:
        raise SettingError("space", f"{where}: is not YAML: {shown(str(exc))}") from None


def load_space(source: str | os.PathLike[str]) -> ParameterSpace:
    """A space from a YAML/JSON file, or from inline text that starts with ``{``.

    Raises:
        SettingError: ``space`` when the file cannot be read, is too large, is not UTF-8 text
            or not a YAML mapping, uses anchors/aliases or nests too deep; else the refused
            field. Every message of a file's refusal starts with ``file <path>:``.
    """
    text = str(source)
    if text.lstrip().startswith("{"):
        if len(text) > MAX_SPACE_BYTES:
            raise SettingError(
                "space",
                f"inline space: is {len(text)} characters, more than the limit of "
                f"{MAX_SPACE_BYTES}",
            )
        try:
            data = json.loads(text)
        except (json.JSONDecodeError, RecursionError) as exc:
            raise SettingError("space", f"inline space is not JSON: {shown(str(exc))}") from None
        return parse_space(data)

    path = Path(source)
    where = f"file {path}"
    raw = _read_limited(path)
    try:
        decoded = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise SettingError(
            "space", f"{where}: is not a YAML mapping (not UTF-8 text: byte {exc.start})"
        ) from None
    if "\x00" in decoded:
        raise SettingError("space", f"{where}: is not a YAML mapping (binary data)")
    data = _parse_yaml(decoded, where)
    if not isinstance(data, Mapping):
        raise SettingError("space", f"{where}: is not a YAML mapping (got {shown(data)})")
    try:
        return parse_space(data, default_name=_stem_name(path))
    except SettingError as exc:
        raise SettingError(exc.field, f"{where}: {exc.reason}") from None
