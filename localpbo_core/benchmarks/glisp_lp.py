"""Benchmark: GLISp's surrogate fit, glis's ``get_rbf_weights`` against :func:`rbf_weights`.

Run ``python -m localpbo_core.benchmarks.glisp_lp``. Two parts:

* **One program per size.** For (d, N) in {(32, 320), (64, 640), (102, 1530)}, the sizes of
  GLISp's last step on Levy 32, the 64-D GP paths and Walker2d: N uniform points, glis's
  inverse-quadratic RBF matrix (shape factor 1), and N − 1 comparisons king-of-the-hill
  style on a smooth random utility with noise (fixed seed), as GLISp makes them. Prints the
  median seconds of glis's fit (``scipy.optimize.linprog``) and of
  :func:`localpbo_core.optimizers.glisp_lp.rbf_weights` over ``--repeats`` solves, their
  ratio, whether the weights are the same bit for bit, and whether presolve ran. These
  programs need fewer simplex iterations than a run's, so the ratio is an upper bound.
* **Whole runs** (``--runs SPEC:RUN,...``, default Levy 32 and the 64-D ℓ = 0.1 GP paths out
  of model, GLISp seed 0): a stored run's plan made again as ``localpbo sweep`` makes it,
  every program it solves (its steps and its recalibrations) fitted both ways. Prints the
  programs, how many gave the same weights bit for bit, the seconds of all fits each way and
  their ratio, and the run's optimizer seconds besides the fits (the particle swarm, mostly).

A script, not a test: it prints figures and asserts nothing.
"""

from __future__ import annotations

import argparse
import statistics
import time
from collections.abc import Callable, Sequence
from functools import partial
from types import SimpleNamespace
from typing import Any, cast

import numpy as np

from localpbo_core.optimizers.glisp import _glis_solvers
from localpbo_core.optimizers.glisp_lp import lp_matrix, presolve_can_reduce, rbf_weights

SIZES = ((32, 320), (64, 640), (102, 1530))
SEPARATION = 1.0 / 100  # glis's σ = 1 / expected_max_evals at GLISp's default E = 100


def glisp_program(d: int, n: int, seed: int) -> tuple[np.ndarray, np.ndarray, int]:
    """The RBF matrix, the comparisons ``[better, worse]`` and the best sample's index of a
    GLISp step with ``n`` samples in ``d`` dimensions (module docstring)."""
    rng = np.random.default_rng(seed)
    X = rng.random((n, d)) * 2.0 - 1.0  # glis's scaled box [-1, 1]^d
    direction = rng.standard_normal(d) / np.sqrt(d)
    utility = -np.sum((X - 0.3) ** 2, axis=1) / d + np.sin(3.0 * X @ direction)
    utility = utility + 0.1 * rng.standard_normal(n)
    M = 1.0 / (1.0 + np.sum((X[:, None, :] - X[None, :, :]) ** 2, axis=-1))
    pairs, best = [], 0
    for k in range(1, n):
        if utility[k] > utility[best]:
            pairs.append([k, best])
            best = k
        else:
            pairs.append([best, k])
    return M, np.array(pairs), best


def add_size_and_run_arguments(parser: argparse.ArgumentParser) -> None:
    """The options GLISp's benchmarks share: ``--max-n`` (skip larger sizes of
    :data:`SIZES`) and ``--runs`` (stored runs to make again, ``SPEC:RUN_ID,...``)."""
    parser.add_argument(
        "--max-n", type=int, default=max(n for _, n in SIZES), help="skip larger sizes"
    )
    parser.add_argument(
        "--runs",
        default="synthetic:levy32__glisp__seed0,gp_out_of_model:gp64_l0.1__glisp__seed0",
        help="whole runs SPEC:RUN_ID, comma-separated; '' for none",
    )


def stored_runs(text: str) -> list[tuple[str, str]]:
    """``--runs``'s ``SPEC:RUN_ID`` items as ``(spec, run_id)`` pairs."""
    pairs = [item.split(":", 1) for item in text.split(",") if item]
    return [(spec, run_id) for spec, run_id in pairs]


def _run_fits(spec: str, run_id: str) -> tuple[int, int, float, float, float]:
    """The stored-run plan ``run_id`` of ``spec`` made again (module docstring): programs,
    programs with the same weights, seconds of glis's fits, of ours, and the run's optimizer
    seconds besides both."""
    from localpbo_core.experiments import load_spec
    from localpbo_core.optimizers import glisp
    from localpbo_core.sweep import execute_run

    glis_fit = cast(Any, _glis_solvers().GLISp).get_rbf_weights
    ours_fit = glisp._fit_rbf_weights
    counts, seconds = [0, 0], [0.0, 0.0]

    def both(
        glis: Any, M: np.ndarray, n: int, prefs: np.ndarray, ties: np.ndarray, ibest: int
    ) -> np.ndarray:
        start = time.perf_counter()
        reference = glis_fit(glis, M, n, prefs, ties, ibest)
        seconds[0] += time.perf_counter() - start
        start = time.perf_counter()
        ours = ours_fit(glis, M, n, prefs, ties, ibest)
        seconds[1] += time.perf_counter() - start
        counts[0] += 1
        counts[1] += bool(np.array_equal(reference, ours))
        return ours

    plan = next(p for p in load_spec(spec).runs() if p.run_id == run_id)
    glisp._fit_rbf_weights = both
    try:
        doc = execute_run(plan)
    finally:
        glisp._fit_rbf_weights = ours_fit
    rest = float(doc["optimizer_seconds"]) - seconds[0] - seconds[1]
    return counts[0], counts[1], seconds[0], seconds[1], rest


def _median_seconds(fit: Callable[[], np.ndarray], repeats: int) -> tuple[float, np.ndarray]:
    times, out = [], np.empty(0)
    for _ in range(repeats):
        start = time.perf_counter()
        out = fit()
        times.append(time.perf_counter() - start)
    return statistics.median(times), out


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m localpbo_core.benchmarks.glisp_lp",
        description="Time GLISp's surrogate fit: glis's linprog path against rbf_weights.",
    )
    parser.add_argument("--repeats", type=int, default=3, help="solves per size (median)")
    parser.add_argument("--seed", type=int, default=0)
    add_size_and_run_arguments(parser)
    args = parser.parse_args(argv)
    glis_fit = cast(Any, _glis_solvers().GLISp).get_rbf_weights
    owner = SimpleNamespace(sepvalue=SEPARATION)
    no_ties = np.zeros((0, 2), dtype=np.intp)
    print(f"{'d':>4} {'N':>5} {'glis s':>9} {'ours s':>9} {'ratio':>7}  same bits  presolve")
    for d, n in SIZES:
        if n > args.max_n:
            continue
        M, pairs, best = glisp_program(d, n, args.seed)
        theirs, reference = _median_seconds(
            partial(glis_fit, owner, M, n, pairs, no_ties, best), args.repeats
        )
        ours, weights = _median_seconds(
            partial(rbf_weights, M, n, pairs, no_ties, best, SEPARATION), args.repeats
        )
        presolve = presolve_can_reduce(lp_matrix(M, n, pairs, no_ties), n, 0)
        print(
            f"{d:>4} {n:>5} {theirs:>9.3f} {ours:>9.3f} {theirs / ours:>6.1f}x"
            f"  {np.array_equal(reference, weights)!s:>9}  {'on' if presolve else 'off'}"
        )
    runs = stored_runs(args.runs)
    if runs:
        print(
            f"\n{'run':<34} {'fits':>6} {'same':>6} {'glis s':>9} {'ours s':>9} "
            f"{'ratio':>7} {'rest s':>8}"
        )
    for spec, run_id in runs:
        fits, same, theirs, ours, rest = _run_fits(spec, run_id)
        print(
            f"{run_id:<34} {fits:>6} {same:>6} {theirs:>9.2f} {ours:>9.2f} "
            f"{theirs / ours:>6.1f}x {rest:>8.2f}"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
