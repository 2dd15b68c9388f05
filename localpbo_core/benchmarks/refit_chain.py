"""Benchmark: warm refits of the pairwise GP after one more duel each (TuRPBO's pattern).

For each size, a cold fit on the first duels, then ``--refits`` warm-started refits that each
add one duel (data as in :mod:`.surrogate_fit`: every new point dueled against a previous one,
exact probit). Every combination of hyperparameter solver (scipy ``l-bfgs-b``, restarting its
curvature at each refit, vs our ``carried-bfgs``, :mod:`localpbo_core.surrogate.box_bfgs`) and
Laplace form (``whitened``, p x p systems, vs ``duels``, m x m systems,
:mod:`localpbo_core.surrogate.duel_space`) runs the same chain. Prints the time and objective
evaluations per refit, the speed-up against ``l-bfgs-b`` + ``whitened`` (the reference: what the
surrogate did before both), and the largest difference in the final log marginal likelihoods.

    OMP_NUM_THREADS=1 python -m localpbo_core.benchmarks.refit_chain [--dim 33] [--sizes ...]

A script, not a test: it prints figures and asserts nothing.
"""

from __future__ import annotations

import argparse
import itertools
import time
from collections.abc import Sequence

import torch

from localpbo_core.benchmarks.surrogate_fit import loop_data
from localpbo_core.surrogate import PairwiseGPSurrogate

SOLVERS = ("l-bfgs-b", "carried-bfgs")
FORMS = ("whitened", "duels")


def run_chain(
    X: torch.Tensor, comp: torch.Tensor, n0: int, refits: int, solver: str, form: str
) -> tuple[float, float, list[float]]:
    """Cold fit on ``n0`` duels then ``refits`` warm refits; returns (seconds per refit,
    evaluations per refit, log marginal likelihood after every refit)."""
    s = PairwiseGPSurrogate.fit(X[: n0 + 1], comp[:n0], solver=solver, form=form)
    seconds, evals, mlls = 0.0, 0, []
    for m in range(n0 + 1, n0 + refits + 1):
        t0 = time.perf_counter()
        s = PairwiseGPSurrogate.fit(X[: m + 1], comp[:m], warm_start=s, solver=solver, form=form)
        seconds += time.perf_counter() - t0
        evals += s.n_evaluations
        mlls.append(s.log_marginal_likelihood)
    return seconds / refits, evals / refits, mlls


def main(argv: Sequence[str] | None = None) -> int:
    """Run the benchmark and print the table."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--dim", type=int, default=33, help="input dimension")
    parser.add_argument("--sizes", default="165,330,495", help="duels at the first refit")
    parser.add_argument("--refits", type=int, default=10, help="warm refits per chain")
    parser.add_argument("--seed", type=int, default=0, help="data seed")
    parser.add_argument("--torch-threads", type=int, default=1, help="torch threads")
    args = parser.parse_args(argv)
    torch.set_num_threads(args.torch_threads)
    print(
        f"warm refits, d={args.dim}, {args.refits} refits per chain, one more duel each, "
        f"torch threads {args.torch_threads}"
    )
    print(
        f"{'n':>5} {'solver':>13} {'form':>9} | {'s/refit':>8} {'evals':>6} {'speed-up':>8} "
        f"| {'final mll':>11} {'max |dmll|':>10}"
    )
    for n in (int(v) for v in args.sizes.split(",")):
        X, comp = loop_data(args.dim, n + args.refits, args.seed)
        rows = {}
        for solver, form in itertools.product(SOLVERS, FORMS):
            rows[solver, form] = run_chain(X, comp, n - 1, args.refits, solver, form)
        ref_s, _, ref_mll = rows["l-bfgs-b", "whitened"]
        for (solver, form), (sec, ev, mll) in rows.items():
            diff = max(abs(a - b) for a, b in zip(mll, ref_mll, strict=True))
            print(
                f"{n:>5} {solver:>13} {form:>9} | {sec:>8.3f} {ev:>6.1f} {ref_s / sec:>7.1f}x "
                f"| {mll[-1]:>11.4f} {diff:>10.1e}"
            )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
