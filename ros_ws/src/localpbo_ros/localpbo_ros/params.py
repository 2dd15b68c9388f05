"""Declared ROS parameters with descriptors and ranges; invalid values refused at start.

Every node setting is a read-only parameter with a description and, for numbers, a range
(``IntegerRange``/``FloatingPointRange``) that rclpy enforces on override; choices and JSON
texts are checked here. Any problem raises :class:`ParameterError` naming the parameter.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor
from rclpy.node import Node

INT_MAX = 2**31 - 1


class ParameterError(ValueError):
    """A node parameter was refused; the message names it."""

    def __init__(self, name: str, problem: str) -> None:
        super().__init__(f"invalid parameter '{name}': {problem}")
        self.name = name


@dataclass(frozen=True)
class Param:
    """One parameter: default, description and constraint (range, choices or JSON object)."""

    name: str
    default: Any
    description: str
    int_range: tuple[int, int] | None = None
    float_range: tuple[float, float] | None = None
    choices: tuple[str, ...] | None = None
    json_object: bool = False

    def descriptor(self) -> ParameterDescriptor:
        """The descriptor (with range) declared to ROS."""
        text = self.description
        if self.choices:
            text += f" One of: {', '.join(self.choices)}."
        desc = ParameterDescriptor(name=self.name, description=text, read_only=True)
        if self.int_range is not None:
            lo, hi = self.int_range
            desc.integer_range = [IntegerRange(from_value=lo, to_value=hi, step=1)]
        if self.float_range is not None:
            lo_f, hi_f = self.float_range
            desc.floating_point_range = [
                FloatingPointRange(from_value=lo_f, to_value=hi_f, step=0.0)
            ]
        return desc

    def check(self, value: Any) -> Any:
        """Validate a value (also the ranges, for values that bypassed ROS)."""
        if type(value) is not type(self.default):
            raise ParameterError(
                self.name, f"expected {type(self.default).__name__}, got {value!r}"
            )
        if self.int_range is not None and not self.int_range[0] <= value <= self.int_range[1]:
            raise ParameterError(self.name, f"{value} is outside {list(self.int_range)}")
        if self.float_range is not None and not (
            self.float_range[0] <= value <= self.float_range[1]
        ):
            raise ParameterError(self.name, f"{value} is outside {list(self.float_range)}")
        if self.choices is not None and value not in self.choices:
            raise ParameterError(self.name, f"{value!r} is not one of {list(self.choices)}")
        if self.json_object:
            try:
                obj = json.loads(value)
            except json.JSONDecodeError as exc:
                raise ParameterError(self.name, f"not JSON: {exc}") from None
            if not isinstance(obj, dict):
                raise ParameterError(self.name, 'must be a JSON object like {"key": 1}')
            return obj
        return value


def declare(node: Node, params: Sequence[Param]) -> dict[str, Any]:
    """Declare ``params`` on ``node`` and return their checked values by name.

    Raises:
        ParameterError: a value of the wrong type, out of range, not a choice, or bad JSON.
    """
    values: dict[str, Any] = {}
    for p in params:
        try:
            node.declare_parameter(p.name, p.default, p.descriptor())
        except Exception as exc:  # rclpy raises several exception types for bad overrides
            raise ParameterError(p.name, f"{type(exc).__name__}: {exc}") from None
        values[p.name] = p.check(node.get_parameter(p.name).value)
    return values
