"""Declared ROS parameters with descriptors and ranges; invalid values refused at start.

Every node setting is a read-only parameter with a description and, for numbers, a range
(``IntegerRange``/``FloatingPointRange``) that rclpy enforces on override; choices and JSON
texts are checked here. Any problem raises :class:`ParameterError` carrying the parameter's
name and a :class:`ParameterReason`; so does a value given for a parameter the node does not
have (:func:`refuse_unknown`: a typo such as ``-p budgte:=30`` is refused with the nearest
names, ROS's own parameters such as ``use_sim_time`` are declared by rclpy and pass).
"""

from __future__ import annotations

import difflib
import json
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from enum import StrEnum
from typing import Any

from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor
from rclpy.exceptions import InvalidParameterTypeException, InvalidParameterValueException
from rclpy.node import Node

INT_MAX = 2**31 - 1


class ParameterReason(StrEnum):
    """Why a parameter value was refused."""

    WRONG_TYPE = "wrong_type"
    """Not of the parameter's type (e.g. text for an integer)."""
    OUT_OF_RANGE = "out_of_range"
    """A number outside the declared range."""
    NOT_A_CHOICE = "not_a_choice"
    """Text that is not one of the allowed choices."""
    BAD_JSON = "bad_json"
    """Text that is not a JSON object."""
    INVALID = "invalid"
    """Refused by the node's own check (a run id, an option the algorithm does not take, a
    directory that does not exist)."""
    UNKNOWN = "unknown"
    """A value for a parameter the node does not declare (a typo, another node's parameter)."""


class ParameterError(ValueError):
    """A node parameter was refused.

    Attributes:
        name: the parameter.
        reason: the kind of problem.
        problem: what is wrong, for people (the message is
            ``invalid parameter '<name>': <problem>``, or ``unknown parameter '<name>'
            <problem>`` for :attr:`ParameterReason.UNKNOWN`).
    """

    def __init__(
        self, name: str, problem: str, reason: ParameterReason = ParameterReason.INVALID
    ) -> None:
        if reason is ParameterReason.UNKNOWN:
            super().__init__(f"unknown parameter '{name}' {problem}")
        else:
            super().__init__(f"invalid parameter '{name}': {problem}")
        self.name = name
        self.reason = reason
        self.problem = problem


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
                self.name,
                f"expected {type(self.default).__name__}, got {value!r}",
                ParameterReason.WRONG_TYPE,
            )
        for bounds in (self.int_range, self.float_range):
            if bounds is not None and not bounds[0] <= value <= bounds[1]:
                raise ParameterError(
                    self.name, f"{value} is outside {list(bounds)}", ParameterReason.OUT_OF_RANGE
                )
        if self.choices is not None and value not in self.choices:
            raise ParameterError(
                self.name,
                f"{value!r} is not one of {list(self.choices)}",
                ParameterReason.NOT_A_CHOICE,
            )
        if self.json_object:
            try:
                obj = json.loads(value)
            except json.JSONDecodeError as exc:
                raise ParameterError(
                    self.name, f"not JSON: {exc}", ParameterReason.BAD_JSON
                ) from None
            if not isinstance(obj, dict):
                raise ParameterError(
                    self.name, 'must be a JSON object like {"key": 1}', ParameterReason.BAD_JSON
                )
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
        except InvalidParameterTypeException as exc:
            raise ParameterError(p.name, str(exc), ParameterReason.WRONG_TYPE) from None
        except InvalidParameterValueException as exc:  # outside the descriptor's range
            raise ParameterError(p.name, str(exc), ParameterReason.OUT_OF_RANGE) from None
        except Exception as exc:  # rclpy raises several other exception types
            raise ParameterError(p.name, f"{type(exc).__name__}: {exc}") from None
        values[p.name] = p.check(node.get_parameter(p.name).value)
    return values


def refuse_unknown(node_name: str, given: Iterable[str], known: Iterable[str]) -> None:
    """Refuse the first name in ``given`` (the values the node received: ``-p``, parameter
    files, constructor overrides) that is not in ``known`` (what the node declares, rclpy's
    own ``use_sim_time`` included); the message suggests the nearest known names.

    Raises:
        ParameterError: ``unknown parameter 'budgte' (did you mean 'budget'?)``, reason
            :attr:`ParameterReason.UNKNOWN`.
    """
    names = sorted(set(known))
    for name in sorted(set(given)):
        if name in names:
            continue
        near = difflib.get_close_matches(name, names, n=3, cutoff=0.6)
        if near:
            hint = f"(did you mean {' or '.join(repr(n) for n in near)}?)"
        else:
            hint = f"({node_name} takes: {', '.join(names)})"
        raise ParameterError(name[:100], hint, ParameterReason.UNKNOWN)
