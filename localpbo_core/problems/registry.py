"""Problem registry: ``make_problem(name, **options)`` and ``available_problems()``.

Synthetic functions live in ``localpbo_core.problems.synthetic``, GP sample paths
(``gp_sample``, options ``dim``, ``lengthscale``, ``instance``, ``num_features``; paper
App. D.4) in ``localpbo_core.problems.gp_samples``; the MuJoCo linear-policy
tasks (``hopper``, ``walker2d``, ``swimmer``) come from ``localpbo_sims`` and are imported
lazily, so ``localpbo_core`` works without mujoco/gymnasium installed.
"""

from __future__ import annotations

import math
from typing import Any

from localpbo_core.validation import SettingError

from .base import Problem
from .gp_samples import GP_SAMPLE_PROBLEM, make_gp_sample
from .synthetic import SYNTHETIC_PROBLEMS, make_synthetic

MUJOCO_PROBLEMS: tuple[str, ...] = ("hopper", "swimmer", "walker2d")
"""Linear-policy tasks of ``localpbo_sims`` (paper Sec. 6 "Policy Search"; swimmer: demo)."""

MUJOCO_OPTIONS: tuple[str, ...] = (
    "alive_bonus",
    "weight_low",
    "weight_high",
    "episode_steps",
    "cache_size",
    "value_range",
    "around_ars",
)
"""The options a MuJoCo task takes (``localpbo_sims.LinearPolicyTask``)."""


def available_problems() -> list[str]:
    """Every registered problem name, sorted."""
    return sorted((*SYNTHETIC_PROBLEMS, GP_SAMPLE_PROBLEM, *MUJOCO_PROBLEMS))


def make_problem(name: str, **options: Any) -> Problem:
    """Create a problem by name.

    Synthetic problems take no options. ``gp_sample`` takes ``dim`` and ``lengthscale``
    (required), ``instance`` (default 0) and ``num_features`` (default 4096). MuJoCo tasks
    accept the keyword options of ``localpbo_sims.LinearPolicyTask`` (``alive_bonus``,
    ``weight_low``, ``weight_high``, ``episode_steps``, ``cache_size``, ``value_range``,
    ``around_ars``).

    Raises:
        ValueError: unknown name (the message lists the valid ones) or unknown option.
    """
    if not isinstance(name, str) or name not in available_problems():
        raise SettingError("problem", f"unknown problem {name!r}; valid: {available_problems()}")
    if name in SYNTHETIC_PROBLEMS:
        if options:
            raise SettingError(sorted(options)[0], f"{name} takes no options")
        return make_synthetic(name)
    if name == GP_SAMPLE_PROBLEM:
        allowed_gp = ("dim", "lengthscale", "instance", "num_features")
        unknown_gp = sorted(set(options) - set(allowed_gp))
        if unknown_gp:
            raise SettingError(unknown_gp[0], f"unknown option for {name}; valid: {allowed_gp}")
        for required in ("dim", "lengthscale"):
            if required not in options:
                raise SettingError(required, f"{name} needs this option")
        return make_gp_sample(**options)
    try:
        import localpbo_sims
    except ImportError as exc:  # pragma: no cover - depends on the installation
        raise ImportError(
            f"problem {name!r} needs localpbo_sims (mujoco, gymnasium): {exc}"
        ) from exc
    allowed = set(MUJOCO_OPTIONS)
    unknown = sorted(set(options) - allowed)
    if unknown:
        raise SettingError(unknown[0], f"unknown option for {name}; valid: {sorted(allowed)}")
    return localpbo_sims.make_task(name, **options)


def recorded_problem_options(
    name: str, options: dict[str, Any], problem: Problem
) -> dict[str, Any]:
    """The problem options a run config records: a MuJoCo task's noise scale made explicit.

    The task's ``value_range`` (the oracle's noise scale, paper Sec. 6) is written into the
    options when they do not give it, so a recorded run is replayed with the scale it was made
    with even if the task's default changes. Other problems' options are returned unchanged.
    """
    out = dict(options)
    if name in MUJOCO_PROBLEMS and "value_range" not in out:
        value_range = float(problem.value_range)
        if math.isfinite(value_range):
            out["value_range"] = value_range
    return out


def replayed_problem_options(name: str, options: dict[str, Any]) -> dict[str, Any]:
    """The problem options of a recorded run config (inverse of
    :func:`recorded_problem_options`): a MuJoCo task recorded without ``value_range`` was made
    when the default noise scale was max − min (``localpbo_sims.MAX_MIN_VALUE_RANGES``), and
    gets that scale back. Other problems' options are returned unchanged."""
    out = dict(options)
    if name in MUJOCO_PROBLEMS and "value_range" not in out and set(out) <= set(MUJOCO_OPTIONS):
        import localpbo_sims

        legacy = localpbo_sims.recorded_value_range(name, **out)
        if math.isfinite(legacy):
            out["value_range"] = legacy
    return out
