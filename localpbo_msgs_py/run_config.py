"""The run configuration on ``std_msgs/msg/String`` holding one JSON object.

``data`` is UTF-8 JSON (no NaN/Infinity, no duplicate keys, at most ``MAX_CONFIG_BYTES``)::

    {"schema": "localpbo/run_config/v1", "run_id": str, "algorithm": str, "task": str,
     "dim": int >= 1, "lower": [float] * dim, "upper": [float] * dim, "seed": int >= 0,
     "budget": int >= 1, "options": {...}}

``lower``/``upper`` is the box of θ in the task's own units (candidates must lie in it),
``budget`` counts evaluations (paper App. D.1), ``options`` holds the algorithm's settings as
a JSON object. Published transient-local depth 1, so the bag alone says how the run was made.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from std_msgs.msg import String

from localpbo_msgs_py._guard import check_type, guarded
from localpbo_msgs_py._validate import (
    check_expected_run,
    check_id,
    check_run_id,
    check_text,
    check_vector,
)
from localpbo_msgs_py.errors import DecodeError, FieldError

TYPE_NAME = "std_msgs/msg/String"
SCHEMA = "localpbo/run_config/v1"
MAX_CONFIG_BYTES = 1 << 20
KEYS = (
    "schema",
    "run_id",
    "algorithm",
    "task",
    "dim",
    "lower",
    "upper",
    "seed",
    "budget",
    "options",
)


def _no_constant(name: str) -> Any:
    raise FieldError("data", f"JSON constant {name} is not allowed (non-finite number)")


def _no_duplicates(pairs: list[tuple[str, Any]]) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for key, value in pairs:
        if key in out:
            raise FieldError("data", f"duplicate JSON key {key!r}")
        out[key] = value
    return out


def _check_int(value: object, name: str, minimum: int) -> int:
    out = check_id(value, name)
    if out < minimum:
        raise FieldError(name, f"must be >= {minimum}, got {out}")
    return out


@dataclass(frozen=True)
class RunConfig:
    """How a run was made: algorithm, task, θ box, seed, budget and algorithm options."""

    run_id: str
    algorithm: str
    task: str
    dim: int
    lower: tuple[float, ...]
    upper: tuple[float, ...]
    seed: int
    budget: int
    options: Mapping[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        check_run_id(self.run_id)
        check_text(self.algorithm, "algorithm", allow_empty=False)
        check_text(self.task, "task", allow_empty=False)
        _check_int(self.dim, "dim", 1)
        lower = check_vector(self.lower, "lower", expected_len=self.dim)
        upper = check_vector(self.upper, "upper", expected_len=self.dim)
        for i, (lo, hi) in enumerate(zip(lower, upper, strict=True)):
            if not lo < hi:
                raise FieldError(f"upper[{i}]", f"must exceed lower[{i}] ({hi!r} <= {lo!r})")
        object.__setattr__(self, "lower", lower)
        object.__setattr__(self, "upper", upper)
        _check_int(self.seed, "seed", 0)
        _check_int(self.budget, "budget", 1)
        if not isinstance(self.options, Mapping):
            raise FieldError("options", f"must be a mapping, got {type(self.options).__name__}")
        try:
            text = json.dumps(dict(self.options), allow_nan=False, sort_keys=True)
        except (TypeError, ValueError) as exc:
            raise FieldError("options", f"not JSON-serialisable: {exc}") from None
        object.__setattr__(self, "options", json.loads(text))

    def to_json(self) -> str:
        """Canonical JSON text (sorted keys)."""
        obj = {
            "schema": SCHEMA,
            "run_id": self.run_id,
            "algorithm": self.algorithm,
            "task": self.task,
            "dim": self.dim,
            "lower": list(self.lower),
            "upper": list(self.upper),
            "seed": self.seed,
            "budget": self.budget,
            "options": self.options,
        }
        return json.dumps(obj, allow_nan=False, sort_keys=True)

    def encode(self) -> String:
        """The ROS message."""
        text = self.to_json()
        if len(text.encode()) > MAX_CONFIG_BYTES:
            raise FieldError("data", f"JSON longer than {MAX_CONFIG_BYTES} bytes")
        return String(data=text)

    @classmethod
    def decode(cls, msg: object, *, expected_run_id: str | None = None) -> RunConfig | DecodeError:
        """Validate and decode."""

        def body() -> RunConfig:
            check_type(msg, String, TYPE_NAME)
            assert isinstance(msg, String)
            if len(msg.data) > MAX_CONFIG_BYTES:
                raise FieldError("data", f"longer than {MAX_CONFIG_BYTES} characters")
            try:
                obj = json.loads(
                    msg.data, parse_constant=_no_constant, object_pairs_hook=_no_duplicates
                )
            except json.JSONDecodeError as exc:
                raise FieldError("data", f"not JSON: {exc}") from None
            if not isinstance(obj, dict):
                raise FieldError("data", f"must be a JSON object, got {type(obj).__name__}")
            for key in KEYS:
                if key not in obj:
                    raise FieldError(key, "missing")
            for key in obj:
                if key not in KEYS:
                    raise FieldError(key, "unexpected key")
            if obj["schema"] != SCHEMA:
                raise FieldError("schema", f"is {obj['schema']!r}, expected {SCHEMA!r}")
            run_id = check_run_id(obj["run_id"])
            check_expected_run(run_id, expected_run_id)
            for key in ("lower", "upper"):
                if not isinstance(obj[key], list):
                    raise FieldError(key, f"must be a list, got {type(obj[key]).__name__}")
            if not isinstance(obj["options"], dict):
                raise FieldError("options", "must be a JSON object")
            return cls(
                run_id,
                obj["algorithm"],
                obj["task"],
                obj["dim"],
                tuple(obj["lower"]),
                tuple(obj["upper"]),
                obj["seed"],
                obj["budget"],
                obj["options"],
            )

        return guarded("run_config", body)
