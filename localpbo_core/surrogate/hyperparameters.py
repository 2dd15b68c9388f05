"""Hyperparameter learning for the pairwise GP by maximising the Laplace evidence (paper Sec. 4;
Chu & Ghahramani 2005, eq. 12) plus the log hyperpriors of BoTorch's default ``PairwiseGP``
kernel: ``Gamma(2.4, 2.7)`` on every lengthscale and ``SmoothedBoxPrior(0.01, 100)`` on the
outputscale. Bounds: lengthscales in ``[0.05, 0.5]`` (paper App. C.2 / D.2), outputscale in
``[0.005, 200]`` (BoTorch's constraint). Optimiser: scipy L-BFGS-B over log-hyperparameters, the
MAP re-solved by warm-started Newton at every evaluation (to ``INNER_NEWTON_TOL``), exact
gradients in closed form from :func:`laplace.log_evidence_and_kernel_gradient` and
:func:`kernel_hyperparameter_gradient` (autograd through :func:`laplace.log_evidence` is kept as
the reference, ``analytic_gradient=False``).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import scipy.optimize
import torch
from gpytorch.priors import GammaPrior, SmoothedBoxPrior
from torch import Tensor

from .kernel import se_kernel
from .laplace import find_map, log_evidence, log_evidence_and_kernel_gradient

LENGTHSCALE_BOUNDS = (0.05, 0.5)
OUTPUTSCALE_BOUNDS = (0.005, 200.0)
# Converted to float64 as BoTorch's model is (``.to(torch.float64)``): left in float32 the log
# densities are rounded to ~1e-7 relative, which is noise for L-BFGS at ftol 1e-10.
_LS_PRIOR = GammaPrior(concentration=2.4, rate=2.7).double()
_OS_PRIOR = SmoothedBoxPrior(a=0.01, b=100.0).double()
# Newton tolerance of the MAP solve inside each objective evaluation. The evidence is then
# evaluated after one more Newton step (quadratic convergence: error ~ tol^2), so the value and
# gradient stay accurate to ~1e-12; the reported MAP is re-solved at find_map's default 1e-11.
INNER_NEWTON_TOL = 1e-6


def log_hyperprior(lengthscale: Tensor, outputscale: Tensor) -> Tensor:
    """Sum of BoTorch's default ``PairwiseGP`` hyperprior log densities."""
    return _LS_PRIOR.log_prob(lengthscale).sum() + _OS_PRIOR.log_prob(outputscale.reshape(1)).sum()


def cholesky_with_jitter(K: Tensor, outputscale: Tensor | float, jitter: float) -> Tensor:
    """Cholesky of ``K + jitter * s * I``; the jitter grows x10 (up to 1e-3 s) if needed."""
    return _cholesky_and_jitter(K, outputscale, jitter)[0]


def _cholesky_and_jitter(
    K: Tensor, outputscale: Tensor | float, jitter: float
) -> tuple[Tensor, float]:
    """:func:`cholesky_with_jitter` that also returns the relative jitter actually used."""
    eye = torch.eye(K.shape[0], dtype=K.dtype)
    j = jitter
    while True:
        L, info = torch.linalg.cholesky_ex(K + (j * outputscale) * eye)
        if int(info) == 0:
            return L, j
        if j >= 1e-3:
            raise ValueError("kernel matrix is not positive definite even with jitter 1e-3")
        j = max(j * 10.0, 1e-10)


@dataclass
class FitResult:
    """Learned or fixed hyperparameters with the MAP in whitened form."""

    lengthscale: Tensor
    outputscale: float
    v_hat: Tensor
    L: Tensor
    log_marginal_likelihood: float
    n_evaluations: int


def evaluate(
    X: Tensor,
    winners: Tensor,
    losers: Tensor,
    lengthscale: Tensor,
    outputscale: Tensor,
    f_init: Tensor,
    jitter: float,
    z_limit: float | None,
    with_prior: bool = True,
) -> tuple[Tensor, Tensor, Tensor]:
    """Objective ``log evidence + log hyperprior`` (differentiable in the hyperparameters).

    ``f_init`` warm-starts the Newton MAP solve. Returns ``(objective, v_hat, L)``.
    """
    K = se_kernel(X, X, lengthscale, outputscale)
    L = cholesky_with_jitter(K, outputscale, jitter)
    v0 = torch.linalg.solve_triangular(L.detach(), f_init.detach().unsqueeze(-1), upper=False)
    v_hat, _ = find_map(L.detach(), winners, losers, v0.squeeze(-1), z_limit, tol=INNER_NEWTON_TOL)
    ev, v1, _ = log_evidence(v_hat, L, winners, losers, z_limit)
    if with_prior:
        ev = ev + log_hyperprior(lengthscale, outputscale)
    return ev, v1, L


def kernel_hyperparameter_gradient(
    X: Tensor, lengthscale: Tensor, outputscale: float, K: Tensor, G: Tensor, jitter_used: float
) -> tuple[Tensor, Tensor]:
    """Chain rule from ``G = dE/dK`` (see :func:`laplace.log_evidence_and_kernel_gradient`) to
    the log-hyperparameters of the ARD SE kernel of paper Sec. 4 ("Prior"),
    ``K_j = K + jitter * s * I`` with ``K_ij = s exp(-0.5 sum_k (x_ik - x_jk)^2 / l_k^2)``:

    * ``dK_j / dlog s = K_j``, so ``dE/dlog s = sum(G * K) + jitter * s * tr(G)``;
    * ``dK_ij / dlog l_k = K_ij (x_ik - x_jk)^2 / l_k^2``, so with ``P = G * K`` (symmetric) and
      ``y = x / l``: ``dE/dlog l_k = 2 (sum_i P_i. y_ik^2 - sum_i y_ik (P y)_ik)``, ``O(p^2 d)``.
      ``X`` is centred first (translation invariance) to limit cancellation.

    Returns ``(dE/dlog l (d,), dE/dlog s (0-d))``.
    """
    P = G * K
    Y = (X - X.mean(0)) / lengthscale
    grad_ls = 2.0 * (P.sum(0) @ (Y * Y) - ((P @ Y) * Y).sum(0))
    grad_os = P.sum() + jitter_used * outputscale * torch.diagonal(G).sum()
    return grad_ls, grad_os


def evaluate_with_gradient(
    X: Tensor,
    winners: Tensor,
    losers: Tensor,
    lengthscale: Tensor,
    outputscale: float,
    f_init: Tensor,
    jitter: float,
    z_limit: float | None,
    with_prior: bool = True,
) -> tuple[float, Tensor, Tensor, Tensor, Tensor]:
    """:func:`evaluate` with the analytic gradient instead of autograd: the objective
    ``log evidence + log hyperprior`` and its gradient w.r.t. ``log lengthscale`` and
    ``log outputscale`` (hyperprior part by autograd on its closed form).

    Returns ``(objective, d objective / dlog l (d,), d objective / dlog s (0-d), v1, L)``.
    """
    with torch.no_grad():
        K = se_kernel(X, X, lengthscale, outputscale)
        L, j = _cholesky_and_jitter(K, outputscale, jitter)
        v0 = torch.linalg.solve_triangular(L, f_init.unsqueeze(-1), upper=False).squeeze(-1)
        v_hat, _ = find_map(L, winners, losers, v0, z_limit, tol=INNER_NEWTON_TOL)
        ev, v1, G = log_evidence_and_kernel_gradient(v_hat, L, winners, losers, z_limit)
        grad_ls, grad_os = kernel_hyperparameter_gradient(X, lengthscale, outputscale, K, G, j)
    value = float(ev)
    if with_prior:
        log_ls = lengthscale.detach().log().requires_grad_(True)
        log_os = torch.tensor(math.log(outputscale), dtype=torch.float64, requires_grad=True)
        prior = log_hyperprior(log_ls.exp(), log_os.exp())
        prior.backward()
        value += float(prior.detach())
        grad_ls = grad_ls + log_ls.grad  # type: ignore[operator]
        grad_os = grad_os + log_os.grad  # type: ignore[operator]
    return value, grad_ls, grad_os, v1, L


def learn_hyperparameters(
    X: Tensor,
    winners: Tensor,
    losers: Tensor,
    lengthscale0: Tensor,
    outputscale0: float,
    learn_lengthscale: bool,
    learn_outputscale: bool,
    f_init: Tensor,
    jitter: float,
    z_limit: float | None,
    maxiter: int = 200,
    ftol: float = 1e-10,
    gtol: float = 1e-6,
    analytic_gradient: bool = True,
) -> FitResult:
    """Maximise evidence + hyperprior with L-BFGS-B over ``log`` hyperparameters within the
    bounds; hyperparameters not learned stay fixed. Every evaluation warm-starts Newton from the
    previous evaluation's MAP. ``analytic_gradient`` selects :func:`evaluate_with_gradient`
    (default) or autograd through :func:`evaluate` (same objective, the reference)."""
    d = X.shape[1]
    ls_lo, ls_hi = (math.log(b) for b in LENGTHSCALE_BOUNDS)
    os_lo, os_hi = (math.log(b) for b in OUTPUTSCALE_BOUNDS)
    x0: list[float] = []
    bounds: list[tuple[float, float]] = []
    if learn_lengthscale:
        x0 += [min(max(math.log(float(v)), ls_lo), ls_hi) for v in lengthscale0]
        bounds += [(ls_lo, ls_hi)] * d
    if learn_outputscale:
        x0.append(min(max(math.log(outputscale0), os_lo), os_hi))
        bounds.append((os_lo, os_hi))
    state = {"f": f_init.detach().clone(), "n": 0}
    best: dict[str, object] = {"value": -math.inf}

    def unpack(theta: Tensor) -> tuple[Tensor, Tensor]:
        ls = theta[:d].exp() if learn_lengthscale else lengthscale0.detach().clone()
        if learn_outputscale:
            os_ = theta[-1].exp()
        else:
            os_ = torch.tensor(outputscale0, dtype=torch.float64)
        return ls, os_

    use_analytic = analytic_gradient and bool(x0)  # nothing learned: value only

    def fun(x: np.ndarray) -> tuple[float, np.ndarray]:
        if use_analytic:
            ls, os_ = unpack(torch.tensor(x, dtype=torch.float64))
            val, g_ls, g_os, v1, L = evaluate_with_gradient(
                X, winners, losers, ls, float(os_), state["f"], jitter, z_limit
            )
            parts = ([-g_ls] if learn_lengthscale else []) + (
                [-g_os.reshape(1)] if learn_outputscale else []
            )
            grad = torch.cat(parts).numpy() if parts else np.zeros_like(x)
        else:
            theta = torch.tensor(x, dtype=torch.float64, requires_grad=True)
            ls, os_ = unpack(theta)
            value, v1, L = evaluate(X, winners, losers, ls, os_, state["f"], jitter, z_limit)
            if value.requires_grad:
                (-value).backward()
            val = float(value.detach())
            grad = theta.grad.numpy().copy() if theta.grad is not None else np.zeros_like(x)
        state["n"] = int(state["n"]) + 1
        if math.isfinite(val):
            state["f"] = (L @ v1).detach()
            if val > float(best["value"]):  # type: ignore[arg-type]
                best.update(value=val, theta=x.copy(), v=v1.detach(), L=L.detach())
        if not math.isfinite(val) or not np.isfinite(grad).all():
            return 1e300, np.zeros_like(x)
        return -val, grad

    fun_typed: Callable[[np.ndarray], tuple[float, np.ndarray]] = fun
    if x0:
        scipy.optimize.minimize(
            fun_typed,
            np.array(x0),
            jac=True,
            method="L-BFGS-B",
            bounds=bounds,
            options={"maxiter": maxiter, "ftol": ftol, "gtol": gtol},
        )
    else:
        fun_typed(np.zeros(0))
    if "theta" not in best:
        raise ValueError("the Laplace evidence is not finite at any evaluated hyperparameters")
    with torch.no_grad():
        ls, os_ = unpack(torch.tensor(best["theta"], dtype=torch.float64))
        L = best["L"]
        # v1 is one Newton step from the converged MAP: a final solve only polishes it.
        v_hat, _ = find_map(L, winners, losers, best["v"], z_limit)  # type: ignore[arg-type]
        value = float(best["value"])  # type: ignore[arg-type]
    return FitResult(
        lengthscale=ls.detach().clone(),
        outputscale=float(os_),
        v_hat=v_hat,
        L=L,
        log_marginal_likelihood=value,
        n_evaluations=int(state["n"]),
    )
