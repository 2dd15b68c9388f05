"""Benchmark: our pairwise GP surrogate vs BoTorch ``PairwiseGP`` + ``fit_gpytorch_mll``.

Run ``python -m localpbo_core.benchmarks.surrogate_fit``. For (d, n) in {(6, 60), (33, 495),
(102, 1530)}: n duels on n + 1 points drawn like an optimisation loop (each new random point
dueled against a random previous one, outcome from a smooth random utility plus noise, fixed
seed). Prints the time of a cold fit with learned hyperparameters, of a warm-started refit after
one more duel, of mean/gradient/Hessian/Sigma_11 at one point, and of BoTorch's fit on the same
n + 1 duels, with both marginal log-likelihoods evaluated by BoTorch's
``PairwiseLaplaceMarginalLogLikelihood`` (same kernel, priors and constraints). Our fits use
``z_limit=3.0`` here so that they maximise exactly the objective BoTorch's mll measures.
A script, not a test: it prints figures and asserts nothing.
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable
from typing import Any, TypeVar

import torch
from torch import Tensor

from localpbo_core.surrogate import PairwiseGPSurrogate

SIZES = ((6, 60), (33, 495), (102, 1530))


def loop_data(d: int, n: int, seed: int) -> tuple[Tensor, Tensor]:
    """``n + 1`` duels on ``n + 2`` points in loop order (the last duel is the 'new' one)."""
    g = torch.Generator().manual_seed(seed)
    X = torch.rand(n + 2, d, generator=g, dtype=torch.float64)
    center = torch.rand(d, generator=g, dtype=torch.float64)
    freq = torch.randn(d, generator=g, dtype=torch.float64) / d**0.5
    y = 4.0 * (-((X - center) ** 2).sum(-1) / d**0.5 + 0.3 * torch.sin(3.0 * X @ freq))
    y = y + 0.1 * torch.randn(n + 2, generator=g, dtype=torch.float64)
    new = torch.arange(1, n + 2)
    old = (torch.rand(n + 1, generator=g, dtype=torch.float64) * new).long()
    win = y[new] > y[old]
    comp = torch.stack([torch.where(win, new, old), torch.where(win, old, new)], dim=1)
    return X, comp


def botorch_model(
    X: Tensor,
    comp: Tensor,
    lengthscale: Tensor | None = None,
    outputscale: float | None = None,
    xtol: float | None = None,
) -> Any:
    """BoTorch ``PairwiseGP`` with the paper's kernel/priors/constraints (App. C.2); the
    hyperparameters given are set and frozen (not learned); ``xtol`` goes to BoTorch's fsolve
    (None = BoTorch's default). Also the reference model of the surrogate tests."""
    from botorch.models import PairwiseGP
    from gpytorch.constraints import Interval
    from gpytorch.kernels import RBFKernel, ScaleKernel
    from gpytorch.priors import GammaPrior, SmoothedBoxPrior

    d = X.shape[1]
    base = RBFKernel(
        ard_num_dims=d,
        lengthscale_prior=GammaPrior(2.4, 2.7),
        lengthscale_constraint=Interval(0.05, 0.5),
    )
    kern = ScaleKernel(
        base,
        outputscale_prior=SmoothedBoxPrior(0.01, 100.0),
        outputscale_constraint=Interval(0.005, 200.0),
    ).to(torch.float64)
    if lengthscale is not None:
        base.lengthscale = torch.as_tensor(lengthscale, dtype=torch.float64).reshape(1, d)
        base.raw_lengthscale.requires_grad_(False)
    if outputscale is not None:
        kern.outputscale = torch.as_tensor(outputscale, dtype=torch.float64)
        kern.raw_outputscale.requires_grad_(False)
    return PairwiseGP(X, comp, covar_module=kern, xtol=xtol)


def botorch_mll(model: Any) -> float:
    """BoTorch's Laplace mll (with hyperpriors) at the model's hyperparameters."""
    from botorch.models.pairwise_gp import PairwiseLaplaceMarginalLogLikelihood

    model.train()
    mll = PairwiseLaplaceMarginalLogLikelihood(model.likelihood, model)
    with torch.no_grad():
        out = model(model.unconsolidated_datapoints)
        return float(mll(out, model.unconsolidated_comparisons))


T = TypeVar("T")


def timed(fn: Callable[[], T], repeats: int = 1) -> tuple[float, T]:
    """Best wall time of ``repeats`` calls, and the last result."""
    best = float("inf")
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t0)
    return best, out


def run(d: int, n: int, seed: int, skip_botorch_above: int) -> dict[str, float]:
    X, comp = loop_data(d, n, seed)
    Xa, ca = X[: n + 1], comp[:n]
    t_cold, cold = timed(lambda: PairwiseGPSurrogate.fit(Xa, ca, z_limit=3.0))
    t_warm, warm = timed(lambda: PairwiseGPSurrogate.fit(X, comp, warm_start=cold, z_limit=3.0))
    t_cold2, cold2 = timed(lambda: PairwiseGPSurrogate.fit(X, comp, z_limit=3.0))
    t_fixed, _ = timed(
        lambda: PairwiseGPSurrogate.fit(
            X, comp, cold.lengthscale, cold.outputscale, warm_start=cold, z_limit=3.0
        )
    )
    x = torch.rand(d, generator=torch.Generator().manual_seed(seed + 1), dtype=torch.float64)
    q = {
        "mean": timed(lambda: warm.mean(x), 5)[0],
        "grad": timed(lambda: warm.mean_gradient(x), 5)[0],
        "hess": timed(lambda: warm.mean_hessian(x), 5)[0],
        "S11": timed(lambda: warm.gradient_covariance(x), 5)[0],
    }
    row: dict[str, float] = {
        "d": d,
        "n": n,
        "cold": t_cold,
        "warm": t_warm,
        "cold_n1": t_cold2,
        "fixed": t_fixed,
        **q,
        "evals_cold": cold2.n_evaluations,
        "evals_warm": warm.n_evaluations,
        "mll_self_warm": warm.log_marginal_likelihood,
        "mll_self_cold": cold2.log_marginal_likelihood,
    }
    if d <= skip_botorch_above:
        from botorch.fit import fit_gpytorch_mll
        from botorch.models.pairwise_gp import PairwiseLaplaceMarginalLogLikelihood

        def bt_fit() -> Any:
            model = botorch_model(X, comp)
            fit_gpytorch_mll(PairwiseLaplaceMarginalLogLikelihood(model.likelihood, model))
            return model

        t_bt, model = timed(bt_fit)
        row["botorch"] = t_bt
        row["mll_botorch"] = botorch_mll(model)
        row["mll_warm"] = botorch_mll(botorch_model(X, comp, warm.lengthscale, warm.outputscale))
        row["mll_cold"] = botorch_mll(botorch_model(X, comp, cold2.lengthscale, cold2.outputscale))
    return row


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--skip-botorch-above",
        type=int,
        default=33,
        help="skip the BoTorch fit for d above this (default 33: at d=102 "
        "BoTorch's fit takes very long)",
    )
    parser.add_argument(
        "--sizes",
        type=str,
        default=",".join(f"{d}:{n}" for d, n in SIZES),
        help="comma-separated d:n list",
    )
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument(
        "--threads",
        type=int,
        default=1,
        help="torch intra-op threads (default 1; the box is shared)",
    )
    args = parser.parse_args(argv)
    torch.set_num_threads(args.threads)
    sizes = [tuple(int(v) for v in s.split(":")) for s in args.sizes.split(",")]
    print(
        f"torch threads={torch.get_num_threads()}  seed={args.seed}  z_limit=3.0 (BoTorch's "
        f"clamp) in our fits; mll = BoTorch PairwiseLaplaceMarginalLogLikelihood incl. priors"
    )
    header = (
        f"{'d':>4} {'n':>5} | {'cold s':>7} {'warm s':>7} {'cold(n+1)':>9} {'fixed s':>7} | "
        f"{'mean ms':>7} {'grad ms':>7} {'hess ms':>7} {'S11 ms':>7} | "
        f"{'BoTorch s':>9} {'BT/warm':>7} {'BT/cold':>7} | "
        f"{'mll warm':>10} {'mll cold':>10} {'mll BT':>10} {'warm-BT':>8}"
    )
    print(header)
    print("-" * len(header))
    for d, n in sizes:
        r = run(d, n, args.seed, args.skip_botorch_above)
        ms = [1e3 * float(r[k]) for k in ("mean", "grad", "hess", "S11")]
        if "botorch" in r:
            bt = float(r["botorch"])
            bt_cols = f"{bt:9.2f} {bt / float(r['warm']):7.1f} {bt / float(r['cold_n1']):7.1f}"
            gap = float(r["mll_warm"]) - float(r["mll_botorch"])
            mll = f"{r['mll_warm']:10.4f} {r['mll_cold']:10.4f} {r['mll_botorch']:10.4f} {gap:8.1e}"
        else:
            bt_cols = f"{'skipped':>9} {'-':>7} {'-':>7}"
            mll = f"{r['mll_self_warm']:10.4f} {r['mll_self_cold']:10.4f} {'-':>10} {'-':>8}"
        print(
            f"{d:4d} {n:5d} | {r['cold']:7.2f} {r['warm']:7.2f} {r['cold_n1']:9.2f} "
            f"{r['fixed']:7.2f} | "
            f"{ms[0]:7.2f} {ms[1]:7.2f} {ms[2]:7.2f} {ms[3]:7.2f} | {bt_cols} | {mll}",
            flush=True,
        )
    print(
        "cold = learned-hyperparameter fit on n duels; warm = refit after one more duel "
        "warm-started from it; cold(n+1) = cold fit on the n+1 duels; fixed = that refit with the "
        "previous hyperparameters held fixed (MAP only); BoTorch = PairwiseGP + "
        "fit_gpytorch_mll on the same n+1 duels. mll columns without BoTorch are our own "
        "objective (identical formula)."
    )


if __name__ == "__main__":
    main()
