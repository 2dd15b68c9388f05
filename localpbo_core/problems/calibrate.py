"""Offline calibration of the problems: value ranges and the Sobol baseline.

``value_range`` convention: the spread of the noise-free value (``true_value``) over the
first N points of ``scipy.stats.qmc.Sobol(d, scramble=True, seed=0)`` on [0,1]^d. Synthetic
functions: max − min over N = 10,000 points (``SYNTHETIC_VALUE_RANGES``). MuJoCo tasks: the
spread between the 1st and 99th percentiles over N = 256 points, 5 episodes per point
(``--quantiles 1,99``; ``localpbo_sims.VALUE_RANGES``, also the policy specs' noise scale):
the returns of random linear policies are heavy-tailed, and on Walker2d one of the 256 points
(a return of −1438, where the 1st–99th percentiles span −202 to −5) sets max − min on its
own, which makes 10 % noise as large as the whole spread of ordinary policies. Their earlier
max − min values are kept as ``localpbo_sims.MAX_MIN_VALUE_RANGES`` for bags recorded then.

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
import multiprocessing
import os
import time
import warnings
from concurrent.futures import ProcessPoolExecutor

import numpy as np
from scipy.stats import qmc

from .base import Problem
from .registry import available_problems, make_problem
from .synthetic import SyntheticProblem


def sobol_points(dim: int, n: int, seed: int) -> np.ndarray:
    """First n points of a scrambled Sobol sequence in [0,1]^dim (scipy, seeded)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)  # n need not be a power of 2 here
        return qmc.Sobol(dim, scramble=True, seed=seed).random(n)


_WORKER_PROBLEM: list[Problem] = []
"""A worker process's problem, made once by :func:`_start_worker`."""


def _start_worker(name: str) -> None:
    _WORKER_PROBLEM[:] = [make_problem(name)]


def _worker_value(point: np.ndarray) -> float:
    return float(_WORKER_PROBLEM[0].true_value(point))


def sobol_values(name: str, n_points: int, workers: int | None = None) -> np.ndarray:
    """``true_value`` at the first n scrambled Sobol points (seed 0) of problem ``name``.

    A MuJoCo task's points are evaluated by ``workers`` processes (default: one per core);
    each value depends on its point only, so the values are the same for any ``workers``."""
    problem = make_problem(name)
    points = sobol_points(problem.dim, n_points, seed=0)
    if isinstance(problem, SyntheticProblem):
        return np.asarray(problem.values(points), dtype=np.float64)
    workers = min(workers or os.cpu_count() or 1, n_points)
    if workers <= 1:
        return np.array([problem.true_value(p) for p in points])
    with ProcessPoolExecutor(
        workers, multiprocessing.get_context("spawn"), _start_worker, (name,)
    ) as pool:
        return np.array(list(pool.map(_worker_value, points, chunksize=4)))


def spread(
    values: np.ndarray, quantiles: tuple[float, float] | None = None
) -> tuple[float, float, float]:
    """(high − low, low, high): the min and max of ``values``, or the two percentiles
    ``quantiles`` (numpy's linear interpolation)."""
    if quantiles is None:
        low, high = float(values.min()), float(values.max())
    else:
        low, high = (float(v) for v in np.percentile(values, quantiles))
    return high - low, low, high


def value_range(
    name: str,
    n_points: int,
    quantiles: tuple[float, float] | None = None,
    workers: int | None = None,
) -> tuple[float, float, float]:
    """(high − low, low, high) of ``true_value`` over n scrambled Sobol points (seed 0):
    max − min, or the spread between the percentiles ``quantiles`` (``workers``: as
    :func:`sobol_values`)."""
    return spread(sobol_values(name, n_points, workers), quantiles)


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
        "--quantiles",
        default="",
        help="LO,HI: the spread between these percentiles instead of max - min (e.g. 1,99)",
    )
    parser.add_argument(
        "--workers",
        type=int,
        default=0,
        help="processes evaluating a MuJoCo task's points (default: one per core)",
    )
    parser.add_argument(
        "--sobol-seeds", default="", help="comma-separated seeds for the Sobol baseline"
    )
    parser.add_argument(
        "--budget", type=int, default=0, help="Sobol baseline budget (default 15d, as the paper)"
    )
    args = parser.parse_args(argv)
    if args.points > 0:
        start = time.perf_counter()
        quantiles = None
        if args.quantiles:
            lo, hi = (float(q) for q in args.quantiles.split(","))
            quantiles = (lo, hi)
        width, low, high = value_range(args.problem, args.points, quantiles, args.workers or None)
        ends = (
            "min, max" if quantiles is None else f"percentiles {quantiles[0]:g}, {quantiles[1]:g}"
        )
        print(
            f"{args.problem}: value_range={width!r} ({ends}: {low:.6g}, {high:.6g}; "
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
