"""Laplace approximation of the pairwise GP posterior (paper Sec. 4, "Posterior").

Probit likelihood with the BoTorch noise convention sigma_n = 1 (eq. likelihood):
``z_n = (f(x_n^+) - f(x_n^-)) / sqrt(2)``, ``p(D | f) = prod_n Phi(z_n)``.

The MAP ``f_hat = argmin S(f)``, ``S(f) = -sum_n log Phi(z_n) + 0.5 f^T K^{-1} f`` is found by
Newton's method in the whitened variable ``v`` with ``f = L v``, ``K = L L^T``:
``S(v) = -log p(D | L v) + 0.5 v^T v`` has Hessian ``B = I + L^T C L`` (``C`` of eq. C), which is
well conditioned (eigenvalues >= 1), so the Newton step
``v <- B^{-1} L^T (C f + grad log p(D | f))`` needs only a Cholesky factor of ``B``.

The Laplace log evidence (Chu & Ghahramani 2005, eq. 12; BoTorch
``PairwiseLaplaceMarginalLogLikelihood``) is ``-S(f_hat) - 0.5 logdet(I + K C)`` with
``det(I + K C) = det(B)``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import torch
from torch import Tensor

SQRT2 = math.sqrt(2.0)
_LOG_SQRT_2PI = 0.5 * math.log(2.0 * math.pi)


@dataclass
class ProbitTerms:
    """``z_n``, ``log Phi(z_n)`` and the hazard ``phi(z_n) / Phi(z_n)`` of every duel;
    ``active`` is False where BoTorch's clamp of ``z`` is active."""

    z: Tensor
    log_cdf: Tensor
    hazard: Tensor
    active: Tensor


def probit_terms(f: Tensor, winners: Tensor, losers: Tensor, z_limit: float | None) -> ProbitTerms:
    """z-scores of eq. (likelihood); ``z_limit`` clamps z as BoTorch does (None = exact)."""
    z = (f[winners] - f[losers]) / SQRT2
    if z_limit is not None:
        active = z.detach().abs() < z_limit
        z = z.clamp(-z_limit, z_limit)
    else:
        active = torch.ones_like(z, dtype=torch.bool)
    log_cdf = torch.special.log_ndtr(z)
    hazard = torch.exp(-0.5 * z * z - _LOG_SQRT_2PI - log_cdf)
    return ProbitTerms(z=z, log_cdf=log_cdf, hazard=hazard, active=active)


def hessian_weights(t: ProbitTerms, jacobian: bool = False) -> Tensor:
    """Per-duel weights ``c_n = 0.5 (hazard_n^2 + z_n hazard_n)`` of eq. (C) (sigma_n = 1).

    With BoTorch's clamp they are evaluated at the clamped ``z`` (BoTorch's ``likelihood_hess``);
    ``jacobian=True`` instead gives the true Jacobian of the clamped gradient (zero weight for
    clamped duels), which Newton's method needs. Without a clamp both are eq. (C)."""
    c = 0.5 * t.hazard * (t.hazard + t.z)
    if jacobian:
        c = torch.where(t.active, c, torch.zeros_like(c))
    return c


def likelihood_hessian(
    t: ProbitTerms, winners: Tensor, losers: Tensor, p: int, jacobian: bool = False
) -> Tensor:
    """The matrix ``C = sum_n c_n h_n h_n^T`` of eq. (C), dense ``(p, p)``, PSD (see
    :func:`hessian_weights`)."""
    c = hessian_weights(t, jacobian)
    flat = torch.zeros(p * p, dtype=c.dtype)
    flat = flat.index_add(0, winners * p + winners, c).index_add(0, losers * p + losers, c)
    flat = flat.index_add(0, winners * p + losers, -c).index_add(0, losers * p + winners, -c)
    return flat.reshape(p, p)


def whitened_precision(L: Tensor, winners: Tensor, losers: Tensor, c: Tensor) -> Tensor:
    """``B = I + L^T C L`` computed as ``I + (H L)^T diag(c) (H L)`` where the rows of ``H L``
    are ``h_n^T L = L[x_n^+] - L[x_n^-]``: one ``O(m p^2)`` product instead of two ``O(p^3)``."""
    HL = L[winners] - L[losers]
    return torch.eye(L.shape[0], dtype=L.dtype) + HL.transpose(0, 1) @ (c.unsqueeze(-1) * HL)


def objective(
    v: Tensor, L: Tensor, winners: Tensor, losers: Tensor, z_limit: float | None
) -> Tensor:
    """``S`` of paper Sec. 4 ("Posterior") in whitened form: ``-log p(D | L v) + 0.5 v^T v``."""
    t = probit_terms(L @ v, winners, losers, z_limit)
    return -t.log_cdf.sum() + 0.5 * (v * v).sum()


def newton_step(
    v: Tensor, L: Tensor, winners: Tensor, losers: Tensor, z_limit: float | None
) -> tuple[Tensor, Tensor, Tensor]:
    """One full Newton step on ``S(v)`` (on the clamped gradient equation if ``z_limit``);
    returns ``(v_new, gradient of S at v, chol(B))``.

    ``v_new = B^{-1} L^T (C f + grad log p(D | f))`` with ``f = L v`` and ``B = I + L^T C L``.
    Differentiable in ``L`` (hence in the kernel hyperparameters) and in ``v``.
    """
    f = L @ v
    t = probit_terms(f, winners, losers, z_limit)
    c = hessian_weights(t, jacobian=True)
    HL = L[winners] - L[losers]  # rows h_n^T L
    B = torch.eye(L.shape[0], dtype=L.dtype) + HL.transpose(0, 1) @ (c.unsqueeze(-1) * HL)
    LB = torch.linalg.cholesky(B)
    # L^T (C f + grad log p) = (H L)^T (c * (H f) + hazard / sqrt(2)),  H f = sqrt(2) z_raw
    g = t.hazard / SQRT2
    rhs = HL.transpose(0, 1) @ (c * (f[winners] - f[losers]) + g)
    v_new = torch.cholesky_solve(rhs.unsqueeze(-1), LB).squeeze(-1)
    grad = v - HL.transpose(0, 1) @ g
    return v_new, grad, LB


@torch.no_grad()
def find_map(
    L: Tensor,
    winners: Tensor,
    losers: Tensor,
    v0: Tensor,
    z_limit: float | None = None,
    tol: float = 1e-11,
    max_iter: int = 200,
) -> tuple[Tensor, int]:
    """Newton's method with backtracking for the whitened MAP ``v_hat`` (``f_hat = L v_hat``).

    With the exact probit, ``S`` is strictly convex and the line search is on ``S``; with
    BoTorch's clamp (``z_limit``) the clamped gradient is not the gradient of the clamped
    objective, so the line search is on the squared norm of that gradient (the equation BoTorch
    solves with ``fsolve``). Stops when the step is below ``tol * (1 + |v|_inf)``.
    Returns ``(v_hat, iterations)``.
    """
    v = v0.clone()

    def merit(vv: Tensor) -> Tensor:
        if z_limit is None:
            return objective(vv, L, winners, losers, None)
        t = probit_terms(L @ vv, winners, losers, z_limit)
        g = vv - (L[winners] - L[losers]).transpose(0, 1) @ (t.hazard / SQRT2)
        return (g * g).sum()

    m = merit(v)
    for it in range(1, max_iter + 1):
        v_new, _, _ = newton_step(v, L, winners, losers, z_limit)
        step = v_new - v
        alpha = 1.0
        for _ in range(40):
            cand = v + alpha * step
            mc = merit(cand)
            if torch.isfinite(mc) and mc <= m + 1e-12 * m.abs():
                break
            alpha *= 0.5
        else:
            return v, it
        v, m = cand, mc
        if (alpha * step).abs().max() <= tol * (1.0 + v.abs().max()):
            return v, it
    return v, max_iter


def log_evidence(
    v_hat: Tensor, L: Tensor, winners: Tensor, losers: Tensor, z_limit: float | None = None
) -> tuple[Tensor, Tensor, Tensor]:
    """Differentiable Laplace log evidence ``-S(f_hat) - 0.5 logdet(I + K C)`` (Chu &
    Ghahramani 2005, eq. 12), through ONE Newton step from the (detached) converged ``v_hat``.

    The Newton map has zero Jacobian in ``v`` at its fixed point, so the returned ``v1`` has the
    implicit-function derivative ``dv_hat / dtheta``; everything downstream (``S``, ``C(f_hat)``
    in the log-determinant) then has exact first derivatives w.r.t. the hyperparameters in ``L``.
    Returns ``(log_evidence, v1, chol(B) at v1)``.
    """
    v1, _, _ = newton_step(v_hat.detach(), L, winners, losers, z_limit)
    f1 = L @ v1
    t = probit_terms(f1, winners, losers, z_limit)
    S = -t.log_cdf.sum() + 0.5 * (v1 * v1).sum()
    B = whitened_precision(L, winners, losers, hessian_weights(t))
    LB = torch.linalg.cholesky(B)
    logdet_B = 2.0 * torch.log(torch.diagonal(LB)).sum()
    return -S.clamp_min(0.0) - 0.5 * logdet_B, v1, LB
