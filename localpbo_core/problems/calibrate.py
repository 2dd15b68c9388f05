"""Offline calibration of the problems: value ranges and the Sobol baseline.

``value_range`` convention (all problems): max − min of the noise-free value (``true_value``)
over the first N points of ``scipy.stats.qmc.Sobol(d, scramble=True, seed=0)`` on [0,1]^d;
N = 10,000 for the synthetic functions, N = 256 for the MuJoCo tasks (5 episodes per point).
The results are stored as constants (``SYNTHETIC_VALUE_RANGES``, ``localpbo_sims.VALUE_RANGES``).

The Sobol baseline reproduces the paper's policy-search reference (App. D.6
"Policy-Search", Sobol column: best-seen after the paper's budget of 15d evaluations): for
each seed, a scrambled Sobol sequence seeded by that seed, one episode per point (episode
seed = evaluation index); the best-seen ``true_value`` and best-seen single-episode return
are printed.

Usage::

    python -m localpbo_core.problems.calibrate --problem hartmann6 --points 10000
    python -m localpbo_core.problems.calibrate --problem hopper --points 256
    python -m localpbo_core.problems.calibrate --problem hopper --sobol-seeds 0,1,2
"""

from __future__ import annotations

import argparse
import time
import warnings

import numpy as np
from scipy.stats import qmc

from .registry import available_problems, make_problem
from .synthetic import SyntheticProblem


def sobol_points(dim: int, n: int, seed: int) -> np.ndarray:
    """First n points of a scrambled Sobol sequence in [0,1]^dim (scipy, seeded)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)  # n need not be a power of 2 here
        return qmc.Sobol(dim, scramble=True, seed=seed).random(n)


def value_range(name: str, n_points: int) -> tuple[float, float, float]:
    """(max − min, min, max) of ``true_value`` over n scrambled Sobol points (seed 0)."""
    problem = make_problem(name)
    points = sobol_points(problem.dim, n_points, seed=0)
    if isinstance(problem, SyntheticProblem):
        values = problem.values(points)
    else:
        values = np.array([problem.true_value(p) for p in points])
    return float(values.max() - values.min()), float(values.min()), float(values.max())


def sobol_baseline(name: str, seed: int, budget: int) -> tuple[float, float]:
    """Best-seen (true_value, single-episode return) of ``budget`` Sobol evaluations."""
    problem = make_problem(name)
    points = sobol_points(problem.dim, budget, seed=seed)
    best_true = -np.inf
    best_episode = -np.inf
    for k, p in enumerate(points):
        best_episode = max(best_episode, problem.evaluate(p, k))
        best_true = max(best_true, problem.true_value(p))
    return float(best_true), float(best_episode)


def main(argv: list[str] | None = None) -> None:
    """Command-line entry point (see module docstring)."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--problem", required=True, choices=available_problems())
    parser.add_argument("--points", type=int, default=0, help="Sobol points for value_range")
    parser.add_argument(
        "--sobol-seeds", default="", help="comma-separated seeds for the Sobol baseline"
    )
    parser.add_argument(
        "--budget", type=int, default=0, help="Sobol baseline budget (default 15d, as the paper)"
    )
    args = parser.parse_args(argv)
    if args.points > 0:
        start = time.perf_counter()
        width, low, high = value_range(args.problem, args.points)
        print(
            f"{args.problem}: value_range={width!r} (min {low:.6g}, max {high:.6g}, "
            f"{args.points} Sobol points, {time.perf_counter() - start:.1f} s)"
        )
    if args.sobol_seeds:
        seeds = [int(s) for s in args.sobol_seeds.split(",")]
        budget = args.budget or 15 * make_problem(args.problem).dim
        rows = []
        for seed in seeds:
            start = time.perf_counter()
            best_true, best_episode = sobol_baseline(args.problem, seed, budget)
            rows.append((best_true, best_episode))
            print(
                f"{args.problem} seed {seed}: best true_value {best_true:.1f}, best episode "
                f"{best_episode:.1f} after {budget} evals ({time.perf_counter() - start:.1f} s)"
            )
        arr = np.array(rows)
        print(
            f"{args.problem} Sobol best-seen over {len(seeds)} seeds: true_value "
            f"{arr[:, 0].mean():.1f} ± {arr[:, 0].std(ddof=1) if len(seeds) > 1 else 0:.1f}, "
            f"episode {arr[:, 1].mean():.1f} ± {arr[:, 1].std(ddof=1) if len(seeds) > 1 else 0:.1f}"
        )


if __name__ == "__main__":
    main()
