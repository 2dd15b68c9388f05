"""Benchmark: GLISp's swarm step, glis's acquisition under pyswarm's ``pso`` against ours.

Run ``python -m localpbo_core.benchmarks.glisp_swarm``. Each GLISp step minimises glis's
acquisition by a particle swarm (20 particles, at most 2,000 iterations). Ours is the same
computation (:mod:`localpbo_core.optimizers.glisp_acquisition` evaluates the acquisition,
:mod:`localpbo_core.optimizers.glisp_pso` runs pyswarm's compiled loop on only the random
factors it reads). Two parts:

* **One swarm per size.** For (d, N) in {(32, 320), (64, 640), (102, 1530)}, the sizes of
  GLISp's last step on Levy 32, the 64-D GP paths and Walker2d: N uniform samples in glis's
  box, random RBF weights, glis's exploration settings. Prints the median seconds per swarm
  over ``--repeats`` seeds of glis's path (its ``inverse_quadratic`` and numba
  ``facquisition_pref_surrogate`` per particle, ``pyswarm.pso``) and of ours, their ratio,
  the swarms' mean iterations and whether every swarm ended at the same point and value bit
  for bit.
* **Whole runs** (``--runs SPEC:RUN,...``, default Levy 32 and the 64-D ℓ = 0.1 GP paths out
  of model, GLISp seed 0): a stored run's plan made again as ``localpbo sweep`` makes it, once
  with glis's path and once with ours. Prints both runs' optimizer seconds, their ratio and
  whether both runs chose the same candidates bit for bit.

A script, not a test: it prints figures and asserts nothing.
"""

from __future__ import annotations

import argparse
import statistics
import time
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
import pyswarm

from localpbo_core.benchmarks.glisp_lp import SIZES, add_size_and_run_arguments, stored_runs
from localpbo_core.optimizers import glisp, glisp_acquisition
from localpbo_core.optimizers.glisp import _glis_solvers
from localpbo_core.optimizers.glisp_acquisition import surrogate_acquisition
from localpbo_core.optimizers.glisp_pso import pso

SWARM, ITERATIONS = 20, 2000  # GLISp's PSOswarmsize and PSOiters defaults
MINFUNC = 1e-4  # glis's dF * PSOminfunc with a surrogate range of about 1


def acquisitions(
    d: int, n: int, seed: int
) -> tuple[Callable[[np.ndarray], float], Callable[[np.ndarray], float]]:
    """glis's acquisition at a step with ``n`` samples in ``d`` dimensions, as glis's
    ``GLISp.update`` builds it, and ours on the same state (module docstring)."""
    solvers: Any = _glis_solvers()
    from glis.rbf import inverse_quadratic

    rng = np.random.default_rng(seed)
    Xs = rng.random((n, d)) * 2.0 - 1.0
    W = rng.standard_normal(n) / n
    feasible, satisfactory = [True] * n, [True] * n
    iw_best = float(np.sum(1.0 / np.sum((Xs[1:] - Xs[0]) ** 2, axis=-1)))
    N, E = float(n - 1), 100.0

    def theirs(xs: np.ndarray) -> float:
        rbf_xs = inverse_quadratic(Xs, xs.T, 1.0)
        return solvers.facquisition_pref_surrogate(
            xs.T, Xs, rbf_xs, W, 0.5, 1.0, 0.0, 0.0, True, N, E, iw_best,
            False, False, np.array(feasible), np.array(satisfactory),
        ) + 0.0  # fmt: skip

    def ours(xs: np.ndarray) -> float:
        return surrogate_acquisition(xs, Xs, W, 1.0, 0.5, 1.0, True, N, E, iw_best) + 0.0

    return theirs, ours


def _swarms(d: int, n: int, repeats: int) -> tuple[float, float, float, bool]:
    """Median seconds of glis's and of our swarm step, the swarms' mean iterations, and
    whether every result was the same."""
    lb, ub = -np.ones(d), np.ones(d)
    theirs, ours, iterations, same = [], [], [], True
    for seed in range(repeats):
        glis_f, our_f = acquisitions(d, n, seed)
        start = time.perf_counter()
        reference = pyswarm.pso(
            glis_f, lb, ub, swarmsize=SWARM, maxiter=ITERATIONS, minfunc=MINFUNC, seed=seed
        )
        theirs.append(time.perf_counter() - start)
        start = time.perf_counter()
        x, fx = pso(our_f, lb, ub, seed=seed, swarmsize=SWARM, maxiter=ITERATIONS, minfunc=MINFUNC)
        ours.append(time.perf_counter() - start)
        iterations.append(reference.nit)
        same = same and bool(np.array_equal(x, reference.x)) and fx == reference.fun
    return statistics.median(theirs), statistics.median(ours), statistics.mean(iterations), same


def _whole_run(spec: str, run_id: str) -> tuple[float, float, bool]:
    """Optimizer seconds of the stored-run plan made again with glis's path and with ours,
    and whether both runs chose the same candidates."""
    from localpbo_core.experiments import load_spec
    from localpbo_core.sweep import execute_run

    plan = next(p for p in load_spec(spec).runs() if p.run_id == run_id)
    docs = []
    fast, reproduces = glisp_acquisition.fast_acquisition, glisp.reproduces_installed_pyswarm
    for ours in (False, True):
        if not ours:
            glisp_acquisition.fast_acquisition = lambda acquisition: None
            glisp.reproduces_installed_pyswarm = lambda: False
        try:
            docs.append(execute_run(plan))
        finally:
            glisp_acquisition.fast_acquisition = fast
            glisp.reproduces_installed_pyswarm = reproduces
    same = docs[0]["candidates"] == docs[1]["candidates"]
    return float(docs[0]["optimizer_seconds"]), float(docs[1]["optimizer_seconds"]), same


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m localpbo_core.benchmarks.glisp_swarm",
        description="Time GLISp's swarm step: glis's acquisition under pyswarm against ours.",
    )
    parser.add_argument("--repeats", type=int, default=5, help="swarms per size (median)")
    add_size_and_run_arguments(parser)
    args = parser.parse_args(argv)
    for f in acquisitions(2, 5, 0):  # numba compiles both before any timing
        f(np.zeros(2))
    print(f"{'d':>4} {'N':>5} {'glis s':>9} {'ours s':>9} {'ratio':>7} {'iters':>6}  same")
    for d, n in SIZES:
        if n > args.max_n:
            continue
        theirs, ours, iterations, same = _swarms(d, n, args.repeats)
        print(
            f"{d:>4} {n:>5} {theirs:>9.4f} {ours:>9.4f} {theirs / ours:>6.1f}x "
            f"{iterations:>6.1f}  {same}"
        )
    runs = stored_runs(args.runs)
    if runs:
        print(f"\n{'run':<34} {'glis s':>9} {'ours s':>9} {'ratio':>7}  same candidates")
    for spec, run_id in runs:
        theirs, ours, same = _whole_run(spec, run_id)
        print(f"{run_id:<34} {theirs:>9.2f} {ours:>9.2f} {theirs / ours:>6.1f}x  {same}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
