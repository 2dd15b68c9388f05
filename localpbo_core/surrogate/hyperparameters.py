"""Hyperparameter learning for the pairwise GP by maximising the Laplace evidence (paper Sec. 4;
Chu & Ghahramani 2005, eq. 12) plus the log hyperpriors of BoTorch's default ``PairwiseGP``
kernel: ``Gamma(2.4, 2.7)`` on every lengthscale and ``SmoothedBoxPrior(0.01, 100)`` on the
outputscale. Bounds: lengthscales in ``[0.05, 0.5]`` (paper App. C.2 / D.2), outputscale in
``[0.005, 100]`` (see ``OUTPUTSCALE_BOUNDS``). Optimiser over log-hyperparameters: a
box-constrained BFGS that carries its curvature from one refit to the next
(:mod:`.box_bfgs`, default) or scipy's L-BFGS-B (the reference, ``solver="l-bfgs-b"``), both
with scipy's L-BFGS-B stopping rules as BoTorch's ``fit_gpytorch_mll`` uses them. The MAP is
re-solved by warm-started Newton at every evaluation (to ``INNER_NEWTON_TOL``); exact gradients
in closed form from :func:`laplace.log_evidence_and_kernel_gradient` and
:func:`kernel_hyperparameter_gradient` (autograd through :func:`laplace.log_evidence` is kept as
the reference, ``analytic_gradient=False``). With "can't tell" answers every function takes
the :class:`.ordinal.Ordinal` likelihood (ties and the threshold ``eps``, held fixed) and the
evidence is that of the ordinal model (Chu & Ghahramani 2005).
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

from .box_bfgs import DEFAULT_FTOL, DEFAULT_GTOL, minimize_box_bfgs
from .duel_space import (
    dual_from_utilities,
    duel_covariance,
    find_mode,
    kernel_gradient_from_duels,
    log_evidence_and_duel_gradient,
)
from .kernel import se_kernel
from .laplace import find_map, log_evidence, log_evidence_and_kernel_gradient
from .ordinal import Ordinal

LENGTHSCALE_BOUNDS = (0.05, 0.5)
# BoTorch constrains the outputscale to [0.005, 200], but its SmoothedBoxPrior(0.01, 100) has a
# Gaussian upper tail of width sigma = 0.01 (log density -5e7 at 200). Searching up to 200 puts a
# cliff into the objective that line searches cannot cross (measured: every warm refit late in
# a Hopper run, where the evidence pushes the outputscale to ~100, ended in a failed line search
# with the hyperparameters unchanged). The search therefore stops at the prior's box edge 100:
# with ``g = dE/dlog s`` at 100, going past it could gain at most ``(g sigma / 100)^2 / 2``
# (1e-8 for g = 1.3, the size measured there), far below the fit tolerance.
OUTPUTSCALE_BOUNDS = (0.005, 100.0)
SOLVERS = ("carried-bfgs", "l-bfgs-b")
FORMS = ("auto", "duels", "whitened")
# Converted to float64 as BoTorch's model is (``.to(torch.float64)``): left in float32 the log
# densities are rounded to ~1e-7 relative, which is noise at the fit's tolerance.
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
    """Learned or fixed hyperparameters with the MAP in whitened form; ``curvature`` is the
    BFGS Hessian approximation over the learned log-hyperparameters (``carried-bfgs`` only),
    the start of the next refit's solve."""

    lengthscale: Tensor
    outputscale: float
    v_hat: Tensor
    L: Tensor
    log_marginal_likelihood: float
    n_evaluations: int
    curvature: np.ndarray | None = None


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
    ordinal: Ordinal | None = None,
) -> tuple[Tensor, Tensor, Tensor]:
    """Objective ``log evidence + log hyperprior`` (differentiable in the hyperparameters).

    ``f_init`` warm-starts the Newton MAP solve. Returns ``(objective, v_hat, L)``.
    """
    K = se_kernel(X, X, lengthscale, outputscale)
    L = cholesky_with_jitter(K, outputscale, jitter)
    v0 = torch.linalg.solve_triangular(L.detach(), f_init.detach().unsqueeze(-1), upper=False)
    v_hat, _ = find_map(
        L.detach(), winners, losers, v0.squeeze(-1), z_limit, tol=INNER_NEWTON_TOL, ordinal=ordinal
    )
    ev, v1, _ = log_evidence(v_hat, L, winners, losers, z_limit, ordinal)
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
      ``X`` is centered first (translation invariance) to limit cancellation.

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
    form: str = "auto",
    ordinal: Ordinal | None = None,
) -> tuple[float, Tensor, Tensor, Tensor]:
    """:func:`evaluate` with the analytic gradient instead of autograd: the objective
    ``log evidence + log hyperprior`` and its gradient w.r.t. ``log lengthscale`` and
    ``log outputscale`` (hyperprior part by autograd on its closed form).

    ``form`` picks how the Laplace approximation is computed: ``"whitened"``
    (:func:`laplace.log_evidence_and_kernel_gradient`, ``p x p`` systems), ``"duels"``
    (:func:`duel_space.log_evidence_and_duel_gradient`, ``m x m`` systems, exact probit only;
    the relative jitter is used as given) or ``"auto"``: duels when ``z_limit`` is None and
    there are no more duels than points. Both give the same value and gradient (tested).

    Returns ``(objective, d objective / dlog l (d,), d objective / dlog s (0-d), f_hat)``
    where ``f_hat`` is the MAP utility at ``X`` (a warm start for the next evaluation).
    """
    if form not in FORMS:
        raise ValueError(f"form: must be one of {FORMS}, got {form!r}")
    use_duels = form == "duels" or (
        form == "auto" and z_limit is None and winners.shape[0] <= X.shape[0]
    )
    if use_duels and z_limit is not None:
        raise ValueError("form: 'duels' supports the exact probit only (z_limit=None)")
    with torch.no_grad():
        K = se_kernel(X, X, lengthscale, outputscale)
        if use_duels:
            j = jitter
            Kj = K + (j * outputscale) * torch.eye(K.shape[0], dtype=K.dtype)
            M = duel_covariance(Kj, winners, losers)
            a0 = dual_from_utilities(f_init, winners, losers, ordinal)
            a_hat, _, _ = find_mode(M, a0, tol=INNER_NEWTON_TOL, ordinal=ordinal)
            ev, a1, G_M = log_evidence_and_duel_gradient(M, a_hat, ordinal)
            G = kernel_gradient_from_duels(G_M, winners, losers, K.shape[0])
            f_hat = a1 @ (Kj[winners] - Kj[losers])  # K H^T a
        else:
            L, j = _cholesky_and_jitter(K, outputscale, jitter)
            v0 = torch.linalg.solve_triangular(L, f_init.unsqueeze(-1), upper=False).squeeze(-1)
            v_hat, _ = find_map(
                L, winners, losers, v0, z_limit, tol=INNER_NEWTON_TOL, ordinal=ordinal
            )
            ev, v1, G = log_evidence_and_kernel_gradient(
                v_hat, L, winners, losers, z_limit, ordinal
            )
            f_hat = L @ v1
        grad_ls, grad_os = kernel_hyperparameter_gradient(X, lengthscale, outputscale, K, G, j)
    value = float(ev)
    if with_prior:
        log_ls = lengthscale.detach().log().requires_grad_(True)
        log_os = torch.tensor(math.log(outputscale), dtype=torch.float64, requires_grad=True)
        prior = log_hyperprior(log_ls.exp(), log_os.exp())
        prior.backward()
        value += float(prior.detach())
        assert log_ls.grad is not None and log_os.grad is not None  # set by backward()
        grad_ls = grad_ls + log_ls.grad
        grad_os = grad_os + log_os.grad
    return value, grad_ls, grad_os, f_hat


@dataclass
class _SearchState:
    """What the hyperparameter search carries between objective evaluations: the MAP that
    warm-starts the next Laplace solve, the evaluation count and the best point so far."""

    f: Tensor
    n: int = 0
    best_value: float = -math.inf
    best_theta: np.ndarray | None = None
    best_f: Tensor | None = None


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
    ftol: float = DEFAULT_FTOL,
    gtol: float = DEFAULT_GTOL,
    analytic_gradient: bool = True,
    solver: str = "carried-bfgs",
    curvature0: np.ndarray | None = None,
    form: str = "auto",
    ordinal: Ordinal | None = None,
) -> FitResult:
    """Maximise evidence + hyperprior over ``log`` hyperparameters within the bounds;
    hyperparameters not learned stay fixed. Every evaluation warm-starts Newton from the
    previous evaluation's MAP. ``analytic_gradient`` selects :func:`evaluate_with_gradient`
    (default) or autograd through :func:`evaluate` (same objective, the reference).

    ``solver``: ``"carried-bfgs"`` (:func:`.box_bfgs.minimize_box_bfgs`, started from
    ``curvature0`` when given, e.g. the previous fit's ``curvature``) or ``"l-bfgs-b"``
    (scipy). ``ftol``/``gtol`` are scipy's L-BFGS-B defaults for both, as in BoTorch's fit.
    ``form``: how each evaluation computes the Laplace approximation, see
    :func:`evaluate_with_gradient`.
    """
    if solver not in SOLVERS:
        raise ValueError(f"solver: must be one of {SOLVERS}, got {solver!r}")
    if form not in FORMS:
        raise ValueError(f"form: must be one of {FORMS}, got {form!r}")
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
    state = _SearchState(f=f_init.detach().clone())

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
            val, g_ls, g_os, f_hat = evaluate_with_gradient(
                X,
                winners,
                losers,
                ls,
                float(os_),
                state.f,
                jitter,
                z_limit,
                form=form,
                ordinal=ordinal,
            )
            parts = ([-g_ls] if learn_lengthscale else []) + (
                [-g_os.reshape(1)] if learn_outputscale else []
            )
            grad = torch.cat(parts).numpy() if parts else np.zeros_like(x)
        else:
            theta = torch.tensor(x, dtype=torch.float64, requires_grad=True)
            ls, os_ = unpack(theta)
            value, v1, L = evaluate(
                X, winners, losers, ls, os_, state.f, jitter, z_limit, ordinal=ordinal
            )
            if value.requires_grad:
                (-value).backward()
            val = float(value.detach())
            grad = theta.grad.numpy().copy() if theta.grad is not None else np.zeros_like(x)
            f_hat = (L @ v1).detach()
        state.n += 1
        if math.isfinite(val):
            state.f = f_hat
            if val > state.best_value:
                state.best_value, state.best_theta, state.best_f = val, x.copy(), f_hat
        if not math.isfinite(val) or not np.isfinite(grad).all():
            return 1e300, np.zeros_like(x)
        return -val, grad

    fun_typed: Callable[[np.ndarray], tuple[float, np.ndarray]] = fun
    curvature: np.ndarray | None = None
    if x0 and solver == "carried-bfgs":
        lo, hi = (np.array(b) for b in zip(*bounds, strict=True))
        if curvature0 is not None and np.shape(curvature0) != (len(x0), len(x0)):
            curvature0 = None  # a different set of learned hyperparameters: start afresh
        res = minimize_box_bfgs(
            fun_typed, np.array(x0), lo, hi, curvature0, maxiter=maxiter, ftol=ftol, gtol=gtol
        )
        curvature = res.hessian
    elif x0:
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
    if state.best_theta is None or state.best_f is None:
        raise ValueError("the Laplace evidence is not finite at any evaluated hyperparameters")
    with torch.no_grad():
        ls, os_ = unpack(torch.tensor(state.best_theta, dtype=torch.float64))
        K = se_kernel(X, X, ls, os_)
        L, j = _cholesky_and_jitter(K, os_, jitter)
        # f is one Newton step from the converged MAP: a final solve only polishes it.
        v0 = torch.linalg.solve_triangular(L, state.best_f.unsqueeze(-1), upper=False)
        v_hat, _ = find_map(L, winners, losers, v0.squeeze(-1), z_limit, ordinal=ordinal)
        value = state.best_value
        if j != jitter:  # K needed more jitter than the search used: report its evidence
            value = float(
                evaluate(X, winners, losers, ls, os_, L @ v_hat, jitter, z_limit, ordinal=ordinal)[
                    0
                ]
            )
    return FitResult(
        lengthscale=ls.detach().clone(),
        outputscale=float(os_),
        v_hat=v_hat,
        L=L,
        log_marginal_likelihood=value,
        n_evaluations=state.n,
        curvature=curvature,
    )
