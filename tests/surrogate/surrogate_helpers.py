"""Shared helpers of the surrogate tests: loop-like duel data and BoTorch reference models."""

from __future__ import annotations

import torch
from botorch.models.pairwise_gp import PairwiseLaplaceMarginalLogLikelihood

from localpbo_core.benchmarks.surrogate_fit import botorch_model as shared_botorch_model


def loop_duels(d: int, n: int, seed: int, noise: float = 0.1, scale: float = 3.0):
    """``n`` duels on ``n + 1`` random points, each new point dueled against a previous one,
    outcomes from a smooth random utility plus Gaussian noise (all from ``seed``)."""
    g = torch.Generator().manual_seed(seed)
    X = torch.rand(n + 1, d, generator=g, dtype=torch.float64)
    center = torch.rand(d, generator=g, dtype=torch.float64)
    freq = torch.randn(d, generator=g, dtype=torch.float64)
    y = scale * (-((X - center) ** 2).sum(-1) + 0.3 * torch.sin(3.0 * X @ freq))
    y = y + noise * torch.randn(n + 1, generator=g, dtype=torch.float64)
    new = torch.arange(1, n + 1)
    old = (torch.rand(n, generator=g, dtype=torch.float64) * new).long()
    win = y[new] > y[old]
    comp = torch.stack([torch.where(win, new, old), torch.where(win, old, new)], dim=1)
    return X, comp


def botorch_model(X, comp, lengthscale=None, outputscale=None, xtol=1e-12):
    """The benchmark's BoTorch reference model, with fsolve tightened for tight comparisons."""
    return shared_botorch_model(X, comp, lengthscale, outputscale, xtol=xtol)


def botorch_mll_value(model) -> float:
    """BoTorch's ``PairwiseLaplaceMarginalLogLikelihood`` (with hyperpriors) at the model's
    current hyperparameters."""
    model.train()
    mll = PairwiseLaplaceMarginalLogLikelihood(model.likelihood, model)
    out = model(model.unconsolidated_datapoints)
    return float(mll(out, model.unconsolidated_comparisons).detach())


def learn_kwargs(data, z_limit: float | None) -> dict:
    """Keyword arguments of ``learn_hyperparameters`` for a cold fit of consolidated ``data``
    (lengthscales 0.3, outputscale 1, zero MAP start, jitter 1e-8), both learned."""
    return dict(
        lengthscale0=torch.full((data.X.shape[1],), 0.3, dtype=torch.float64),
        outputscale0=1.0,
        learn_lengthscale=True,
        learn_outputscale=True,
        f_init=torch.zeros(data.X.shape[0], dtype=torch.float64),
        jitter=1e-8,
        z_limit=z_limit,
    )
