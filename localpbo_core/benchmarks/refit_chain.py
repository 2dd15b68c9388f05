"""Benchmark: warm refits of the pairwise GP after one more duel each (TuRPBO's pattern).

For each size, a cold fit on the first duels, then ``--refits`` warm-started refits that each
add one duel (data as in :mod:`.surrogate_fit`: every new point dueled against a previous one,
exact probit). Every combination of hyperparameter solver (scipy ``l-bfgs-b``, restarting its
curvature at each refit, vs our ``carried-bfgs``, :mod:`localpbo_core.surrogate.box_bfgs`) and
Laplace form (``whitened``, p x p systems, vs ``duels``, m x m systems,
:mod:`localpbo_core.surrogate.duel_space`) runs the same chain. ``--source hopper`` takes the
duels of a real TuRPBO run on Hopper instead (165 random evaluations then TuRPBO, 10% noise;
the run itself takes about a minute): there the outputscale sits at its upper bound and most
lengthscales at theirs, the regime of the compute target. Prints the time and objective
evaluations per refit, the speed-up against ``l-bfgs-b`` + ``whitened`` (the reference: what the
surrogate did before both), and the largest difference in the final log marginal likelihoods.

    python -m localpbo_core.benchmarks.refit_chain [--sizes 165,330,495]
    python -m localpbo_core.benchmarks.refit_chain --source hopper --sizes 445

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
) -> tuple[float, float, list[float], float]:
    """Cold fit on ``n0`` duels then ``refits`` warm refits; returns (seconds per refit,
    evaluations per refit, log marginal likelihood after every refit, final outputscale)."""
    s = PairwiseGPSurrogate.fit(X[: n0 + 1], comp[:n0], solver=solver, form=form)
    seconds, evals, mlls = 0.0, 0, []
    for m in range(n0 + 1, n0 + refits + 1):
        t0 = time.perf_counter()
        s = PairwiseGPSurrogate.fit(X[: m + 1], comp[:m], warm_start=s, solver=solver, form=form)
        seconds += time.perf_counter() - t0
        evals += s.n_evaluations
        mlls.append(s.log_marginal_likelihood)
    return seconds / refits, evals / refits, mlls, s.outputscale


def hopper_duels(evaluations: int, seed: int) -> tuple[torch.Tensor, torch.Tensor]:
    """Points and duels of a TuRPBO run on Hopper (165 random evaluations first, 10% noise)."""
    from localpbo_core.loop import run_session
    from localpbo_core.session import RunSettings, Session

    settings = RunSettings(
        algorithm="turpbo", problem="hopper", seed=seed, budget=evaluations, initial_design=165
    )
    session = Session(settings)
    run_session(session)
    opt = session.optimizer
    X = torch.tensor(opt.train_inputs(), dtype=torch.float64)
    return X, torch.tensor(opt.comparisons(), dtype=torch.long)


def main(argv: Sequence[str] | None = None) -> int:
    """Run the benchmark and print the table."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--dim", type=int, default=33, help="input dimension")
    parser.add_argument("--sizes", default="165,330,495", help="duels at the first refit")
    parser.add_argument("--refits", type=int, default=10, help="warm refits per chain")
    parser.add_argument("--seed", type=int, default=0, help="data seed")
    parser.add_argument(
        "--source",
        choices=("synthetic", "hopper"),
        default="synthetic",
        help="duels of the synthetic loop data or of a TuRPBO run on Hopper",
    )
    parser.add_argument("--torch-threads", type=int, default=1, help="torch threads")
    args = parser.parse_args(argv)
    torch.set_num_threads(args.torch_threads)
    sizes = [int(v) for v in args.sizes.split(",")]
    run = hopper_duels(max(sizes) + args.refits + 1, args.seed) if args.source == "hopper" else None
    dim = args.dim if run is None else run[0].shape[1]
    print(
        f"warm refits on {args.source} duels, d={dim}, {args.refits} refits per chain, one more "
        f"duel each, torch threads {args.torch_threads}"
    )
    print(
        f"{'n':>5} {'solver':>13} {'form':>9} | {'s/refit':>8} {'evals':>6} "
        f"{'speed-up':>8} | {'final mll':>11} {'max |dmll|':>10} {'os':>6}"
    )
    for n in sizes:
        X, comp = run if run is not None else loop_data(dim, n + args.refits, args.seed)
        rows = {}
        for solver, form in itertools.product(SOLVERS, FORMS):
            rows[solver, form] = run_chain(X, comp, n - 1, args.refits, solver, form)
        ref_s, _, ref_mll, _ = rows["l-bfgs-b", "whitened"]
        for (solver, form), (sec, ev, mll, os_) in rows.items():
            diff = max(abs(a - b) for a, b in zip(mll, ref_mll, strict=True))
            print(
                f"{n:>5} {solver:>13} {form:>9} | {sec:>8.3f} {ev:>6.1f} "
                f"{ref_s / sec:>7.1f}x | {mll[-1]:>11.4f} {diff:>10.1e} {os_:>6.3g}"
            )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
