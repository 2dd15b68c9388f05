"""Fabricated stored runs and run documents for the tests of the results page's tables,
claims and diagnoses: every number is chosen by the test, nothing is run."""

from __future__ import annotations

from typing import Any

import numpy as np

from localpbo_core.report import StoredRun


def stored_run(
    spec: str,
    problem: str,
    label: str,
    seed: int,
    best: float,
    cum: float,
    seconds: float = 1.0,
    *,
    algorithm: str = "",
    variant: str = "",
    noise: float = 0.1,
) -> StoredRun:
    """A stored run of ``label`` (algorithm ``algorithm`` or the label itself) ending at final
    best-seen ``best`` and cumulative ``cum``; a ``gp<d>_l<lengthscale>`` problem becomes a
    GP sample path of that size, within model for a ``gp_within`` spec."""
    options: dict[str, object] = {}
    name = problem
    if problem.startswith("gp"):
        dim, ls = problem[2:].split("_l")
        options = {"dim": int(dim), "lengthscale": float(ls), "instance": seed}
        name = "gp_sample"
    return StoredRun(
        spec=spec,
        problem_label=problem,
        algorithm_label=label,
        variant=variant,
        seed=seed,
        within_model=spec.endswith("gp_within"),
        settings={
            "problem": name,
            "algorithm": algorithm or label,
            "seed": seed,
            "problem_options": options,
            "optimizer_options": {},
            "budget": None,
            "initial_design": 2,
            "noise_fraction": noise,
        },
        best_seen=np.array([best - 1.0, best]),
        cumulative=np.array([cum / 2, cum]),
        optimizer_seconds=seconds,
    )


def run_document(
    algorithm: str,
    seed: int,
    natives: list[list[float]],
    values: list[float],
    answers: list[dict[str, Any]],
) -> dict[str, Any]:
    """A stored run document (schema ``localpbo/run/v1``) on the test problem ``box`` with the
    given candidates, their true values and the duels' answers."""
    return {
        "schema": "localpbo/run/v1",
        "settings": {
            "problem": "box",
            "algorithm": algorithm,
            "seed": seed,
            "initial_design": 2,
            "noise_fraction": 0.1,
        },
        "candidates": [
            {"id": i, "native": n, "value": v}
            for i, (n, v) in enumerate(zip(natives, values, strict=True))
        ],
        "answers": answers,
    }
