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
    check_cap,
    check_expected_run,
    check_minimum,
    check_run_id,
    check_text,
    check_vector,
    repeated_key,
    require_keys,
    wrong_type,
)
from localpbo_msgs_py.errors import DecodeError, DecodeReason, FieldError

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


R = DecodeReason


def _no_constant(name: str) -> Any:
    raise FieldError("data", R.NON_FINITE, f"JSON constant {name} is not allowed")


def _no_duplicates(pairs: list[tuple[str, Any]]) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for key, value in pairs:
        if key in out:
            raise repeated_key("data", key)
        out[key] = value
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
        check_minimum(self.dim, "dim", 1)
        lower = check_vector(self.lower, "lower", expected_len=self.dim)
        upper = check_vector(self.upper, "upper", expected_len=self.dim)
        for i, (lo, hi) in enumerate(zip(lower, upper, strict=True)):
            if not lo < hi:
                raise FieldError(
                    f"upper[{i}]", R.INCONSISTENT, f"must exceed lower[{i}] ({hi!r} <= {lo!r})"
                )
        object.__setattr__(self, "lower", lower)
        object.__setattr__(self, "upper", upper)
        check_minimum(self.seed, "seed", 0)
        check_minimum(self.budget, "budget", 1)
        if not isinstance(self.options, Mapping):
            raise wrong_type("options", "a JSON object (mapping)", self.options)
        try:
            text = json.dumps(dict(self.options), allow_nan=False, sort_keys=True)
        except (TypeError, ValueError) as exc:
            raise FieldError("options", R.MALFORMED, f"not JSON-serialisable: {exc}") from None
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
        check_cap(len(text.encode()), MAX_CONFIG_BYTES, "data", "bytes")
        return String(data=text)

    @classmethod
    def decode(cls, msg: object, *, expected_run_id: str | None = None) -> RunConfig | DecodeError:
        """Validate and decode."""

        def body() -> RunConfig:
            check_type(msg, String, TYPE_NAME)
            assert isinstance(msg, String)
            # characters bound the bytes from below: a cheap first cap before encoding
            check_cap(len(msg.data), MAX_CONFIG_BYTES, "data", "characters")
            check_cap(len(msg.data.encode()), MAX_CONFIG_BYTES, "data", "bytes")
            try:
                obj = json.loads(
                    msg.data, parse_constant=_no_constant, object_pairs_hook=_no_duplicates
                )
            except json.JSONDecodeError as exc:
                raise FieldError("data", R.MALFORMED, f"not JSON: {exc}") from None
            if not isinstance(obj, dict):
                raise wrong_type("data", "a JSON object", obj)
            require_keys(obj, KEYS)
            if obj["schema"] != SCHEMA:
                raise FieldError(
                    "schema", R.MALFORMED, f"is {str(obj['schema'])[:80]!r}, expected {SCHEMA!r}"
                )
            run_id = check_run_id(obj["run_id"])
            check_expected_run(run_id, expected_run_id)
            for key in ("lower", "upper"):
                if not isinstance(obj[key], list):
                    raise wrong_type(key, "a list", obj[key])
            if not isinstance(obj["options"], dict):
                raise wrong_type("options", "a JSON object", obj["options"])
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
