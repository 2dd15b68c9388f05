"""Run configs for tests, from the keywords a test reads best."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from localpbo_ros.driver import make_run_config

from localpbo_core.settings import DEFAULT_NOISE_FRACTION, RunSettings
from localpbo_msgs_py import RunConfig


def run_config(
    *,
    run_id: str,
    algorithm: str,
    task: str,
    seed: int = 0,
    budget: int | None = None,
    task_options: Mapping[str, Any] | None = None,
    optimizer_options: Mapping[str, Any] | None = None,
    noise_fraction: float = DEFAULT_NOISE_FRACTION,
    failure_policy: str = "retry",
    max_retries: int = 2,
) -> RunConfig:
    """``make_run_config`` of the settings these keywords describe (``initial_design`` may
    come inside ``optimizer_options``, as in a recorded run config)."""
    options = dict(optimizer_options or {})
    initial = options.pop("initial_design", 2)
    settings = RunSettings(
        algorithm=algorithm,
        problem=task,
        seed=seed,
        budget=budget,
        initial_design=initial,
        noise_fraction=noise_fraction,
        optimizer_options=options,
        problem_options=dict(task_options or {}),
    )
    return make_run_config(run_id, settings, failure_policy=failure_policy, max_retries=max_retries)
