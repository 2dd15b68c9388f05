"""Laplace approximation of the pairwise GP posterior (paper Sec. 4, "Posterior").

Probit likelihood with the BoTorch noise convention sigma_n = 1 (eq. (5) "likelihood"):
``z_n = (f(x_n^+) - f(x_n^-)) / sqrt(2)``, ``p(D | f) = prod_n Phi(z_n)``.

The MAP ``f_hat = argmin S(f)``, ``S(f) = -sum_n log Phi(z_n) + 0.5 f^T K^{-1} f`` is found by
Newton's method in the whitened variable ``v`` with ``f = L v``, ``K = L L^T``:
``S(v) = -log p(D | L v) + 0.5 v^T v`` has Hessian ``B = I + L^T C L`` (``C`` of eq. (8)), which is
well conditioned (eigenvalues >= 1), so the Newton step
``v <- B^{-1} L^T (C f + grad log p(D | f))`` needs only a Cholesky factor of ``B``.

The Laplace log evidence (Chu & Ghahramani 2005, eq. 12; BoTorch
``PairwiseLaplaceMarginalLogLikelihood``) is ``-S(f_hat) - 0.5 logdet(I + K C)`` with
``det(I + K C) = det(B)``.

"Can't tell" answers: every function takes an optional :class:`.ordinal.Ordinal` (which duels
are ties, and the indifference threshold ``eps``). Decisive duels then have
``z_n = (g_n - eps) / sqrt(2)`` and ties the interval likelihood of :mod:`.ordinal`; everything
above holds with ``log Phi(z_n)`` replaced by the per-duel log-likelihood, the gradient
``hazard_n / sqrt(2)`` by ``dlog p_n / dg_n`` and eq. (8)'s ``c_n`` by ``-d^2 log p_n / dg_n^2``
(all concave in ``g_n``). ``None`` (or no tie with ``eps = 0``) is the paper's probit exactly.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import torch
from scipy.linalg.blas import dsyrk
from torch import Tensor

from .ordinal import Ordinal, tie_terms

SQRT2 = math.sqrt(2.0)
_LOG_SQRT_2PI = 0.5 * math.log(2.0 * math.pi)


@dataclass
class ProbitTerms:
    """``z_n``, ``log Phi(z_n)`` and the hazard ``phi(z_n) / Phi(z_n)`` of every duel;
    ``active`` is False where BoTorch's clamp of ``z`` is active.

    With an :class:`.ordinal.Ordinal` likelihood, ``log_cdf`` is each duel's log-likelihood,
    ``hazard / sqrt(2)`` its derivative in ``g``, and ``weight`` / ``weight_slope`` hold
    ``c_n = -d^2 log p_n / dg_n^2`` and ``sqrt(2) dc_n / dg_n`` (None: the probit formulas of
    :func:`hessian_weights` and :func:`hessian_weight_slope` in ``z``)."""

    z: Tensor
    log_cdf: Tensor
    hazard: Tensor
    active: Tensor
    weight: Tensor | None = None
    weight_slope: Tensor | None = None


def probit_terms(
    f: Tensor,
    winners: Tensor,
    losers: Tensor,
    z_limit: float | None,
    ordinal: Ordinal | None = None,
) -> ProbitTerms:
    """z-scores of eq. (5) "likelihood"; ``z_limit`` clamps z as BoTorch does (None = exact)."""
    return probit_terms_of_differences(f[winners] - f[losers], z_limit, ordinal)


def probit_terms_of_differences(
    g: Tensor, z_limit: float | None, ordinal: Ordinal | None = None
) -> ProbitTerms:
    """:func:`probit_terms` from the utility differences ``g_n = f(x_n^+) - f(x_n^-)``."""
    if ordinal is not None and not ordinal.is_plain:
        if z_limit is not None:
            raise ValueError("ties and tie_threshold > 0 need the exact probit (z_limit=None)")
        return _ordinal_terms(g, ordinal)
    z = g / SQRT2
    if z_limit is not None:
        active = z.detach().abs() < z_limit
        z = z.clamp(-z_limit, z_limit)
    else:
        active = torch.ones_like(z, dtype=torch.bool)
    log_cdf = torch.special.log_ndtr(z)
    return ProbitTerms(z=z, log_cdf=log_cdf, hazard=probit_hazard(z, log_cdf), active=active)


#: Below this ``z`` :func:`probit_hazard` uses ``erfcx``: in ``exp(-z^2/2 - log Phi(z))`` the
#: two terms of size ``z^2/2`` cancel and digits are lost (all of them by ``|z| ~ 1e8``).
HAZARD_TAIL_Z = -20.0
#: Below this ``z`` :func:`probit_weight` and :func:`probit_weight_slope` use asymptotic
#: series: in the plain formulas ``h + z ~ -1/z`` cancels (at ``z = -14`` they are still good
#: to about 1e-11 and 1e-7 relative; their errors grow like ``z^2`` and ``z^6``).
WEIGHT_TAIL_Z = -14.0
_LOG_NDTR_TAIL = float(torch.special.log_ndtr(torch.tensor(HAZARD_TAIL_Z, dtype=torch.float64)))


def probit_hazard(z: Tensor, log_cdf: Tensor) -> Tensor:
    """The hazard ``h(z) = phi(z) / Phi(z)`` given ``log_cdf = log Phi(z)``, accurate for every
    ``z``: ``exp(-z^2/2 - log sqrt(2 pi) - log Phi(z))`` for ``z >= -20`` and
    ``sqrt(2 / pi) / erfcx(-z / sqrt(2))`` below (``erfcx(x) = exp(x^2) erfc(x)``, so
    ``Phi(z) = erfcx(-z/sqrt(2)) phi(z) sqrt(pi/2)`` exactly). Each branch only sees its own
    range of ``z``, so neither can put a NaN into a gradient."""
    low = z < HAZARD_TAIL_Z
    if not bool(low.any()):
        return torch.exp(-0.5 * z * z - _LOG_SQRT_2PI - log_cdf)
    zc = torch.where(low, torch.full_like(z, HAZARD_TAIL_Z), z)
    lc = torch.where(low, torch.full_like(log_cdf, _LOG_NDTR_TAIL), log_cdf)
    direct = torch.exp(-0.5 * zc * zc - _LOG_SQRT_2PI - lc)
    zt = torch.where(low, z, torch.full_like(z, HAZARD_TAIL_Z))
    tail = math.sqrt(2.0 / math.pi) / torch.special.erfcx(-zt / SQRT2)
    return torch.where(low, tail, direct)


# Asymptotic series in t = 1/z^2 of c (below) and of -z dc/dz as z -> -infinity, from the
# Mills ratio's (1 - Phi(x)) / phi(x) ~ sum_k (-1)^k (2k-1)!! / x^(2k+1), x = -z (12 terms:
# relative error below 1e-13 for z < -14).
_WEIGHT_SERIES = (
    0.5, -0.5, 3.0, -25.0, 259.0, -3177.0, 44891.0, -717665.0, 12812955.0, -252892561.0,
    5472355699.0, -128917192425.0,
)  # fmt: skip
_SLOPE_SERIES = (
    0.0, -1.0, 12.0, -150.0, 2072.0, -31770.0, 538692.0, -10047310.0, 205007280.0,
    -4552066098.0, 109447113980.0, -2836178233350.0,
)  # fmt: skip


def _series(coefficients: tuple[float, ...], t: Tensor) -> Tensor:
    """``sum_k coefficients[k] t^k`` by Horner's rule."""
    acc = torch.full_like(t, coefficients[-1])
    for c in reversed(coefficients[:-1]):
        acc = acc * t + c
    return acc


def _tail_split(z: Tensor, hazard: Tensor, switch: float) -> tuple[Tensor, Tensor, Tensor, Tensor]:
    """The mask ``z < switch``, ``z`` and ``hazard`` moved into the plain range there, and ``z``
    moved into the tail elsewhere (each branch only sees its own range: no NaN in gradients)."""
    low = z < switch
    zc = torch.where(low, torch.full_like(z, switch), z)
    hc = torch.where(low, torch.ones_like(hazard), hazard)
    zt = torch.where(low, z, torch.full_like(z, switch))
    return low, zc, hc, zt


def probit_weight(z: Tensor, hazard: Tensor) -> Tensor:
    """``c = 0.5 h (h + z) = -0.5 d^2 log Phi(z) / dz^2`` (eq. (8), sigma_n = 1) from the
    hazard ``h``; below ``z = -14`` its asymptotic series ``0.5 - 0.5/z^2 + 3/z^4 - ...``."""
    if not bool((z < WEIGHT_TAIL_Z).any()):
        return 0.5 * hazard * (hazard + z)
    low, zc, hc, zt = _tail_split(z, hazard, WEIGHT_TAIL_Z)
    return torch.where(low, _series(_WEIGHT_SERIES, 1.0 / (zt * zt)), 0.5 * hc * (hc + zc))


def probit_weight_slope(z: Tensor, hazard: Tensor) -> Tensor:
    """``dc/dz = 0.5 h (1 - (z + h)(z + 2h))`` of :func:`probit_weight` (``dh/dz = -h (z + h)``);
    below ``z = -14`` its asymptotic series ``1/z^3 - 12/z^5 + 150/z^7 - ...``."""
    if not bool((z < WEIGHT_TAIL_Z).any()):
        return 0.5 * hazard * (1.0 - (z + hazard) * (z + 2.0 * hazard))
    low, zc, hc, zt = _tail_split(z, hazard, WEIGHT_TAIL_Z)
    direct = 0.5 * hc * (1.0 - (zc + hc) * (zc + 2.0 * hc))
    return torch.where(low, -_series(_SLOPE_SERIES, 1.0 / (zt * zt)) / zt, direct)


def _ordinal_terms(g: Tensor, ordinal: Ordinal) -> ProbitTerms:
    """:class:`ProbitTerms` of the ordinal likelihood of :mod:`.ordinal`: the probit of
    ``(g - eps) / sqrt(2)`` for decisive duels, the interval likelihood for ties."""
    z = (g - ordinal.threshold) / SQRT2
    log_cdf = torch.special.log_ndtr(z)
    hazard = probit_hazard(z, log_cdf)
    weight = probit_weight(z, hazard)
    slope = probit_weight_slope(z, hazard)
    tie = ordinal.tie
    if bool(tie.any()):
        tt = tie_terms(g, ordinal.threshold)
        log_cdf = torch.where(tie, tt.log_lik, log_cdf)
        hazard = torch.where(tie, SQRT2 * tt.d1, hazard)
        weight = torch.where(tie, tt.weight, weight)
        slope = torch.where(tie, SQRT2 * tt.weight_slope, slope)
    active = torch.ones_like(z, dtype=torch.bool)
    return ProbitTerms(z, log_cdf, hazard, active, weight=weight, weight_slope=slope)


def hessian_weights(t: ProbitTerms, jacobian: bool = False) -> Tensor:
    """Per-duel weights ``c_n = 0.5 (hazard_n^2 + z_n hazard_n)`` of eq. (8) (sigma_n = 1).

    With BoTorch's clamp they are evaluated at the clamped ``z`` (BoTorch's ``likelihood_hess``);
    ``jacobian=True`` instead gives the true Jacobian of the clamped gradient (zero weight for
    clamped duels), which Newton's method needs. Without a clamp both are eq. (8). With an
    ordinal likelihood they are its ``-d^2 log p_n / dg_n^2`` (``t.weight``)."""
    if t.weight is not None:
        return t.weight
    c = probit_weight(t.z, t.hazard)
    if jacobian:
        c = torch.where(t.active, c, torch.zeros_like(c))
    return c


def likelihood_hessian(
    t: ProbitTerms, winners: Tensor, losers: Tensor, p: int, jacobian: bool = False
) -> Tensor:
    """The matrix ``C = sum_n c_n h_n h_n^T`` of eq. (8), dense ``(p, p)``, PSD (see
    :func:`hessian_weights`)."""
    c = hessian_weights(t, jacobian)
    flat = torch.zeros(p * p, dtype=c.dtype)
    flat = flat.index_add(0, winners * p + winners, c).index_add(0, losers * p + losers, c)
    flat = flat.index_add(0, winners * p + losers, -c).index_add(0, losers * p + winners, -c)
    return flat.reshape(p, p)


def precision_from_rows(HL: Tensor, c: Tensor) -> Tensor:
    """``B = I + (H L)^T diag(c) (H L)`` for the rows ``HL`` ``(m, p)`` and weights ``c >= 0``.

    Without autograd the symmetric product is one BLAS ``dsyrk`` on ``sqrt(c) * HL`` (half the
    flops of a general product); with autograd it is the plain differentiable product."""
    p = HL.shape[1]
    if torch.is_grad_enabled() and (HL.requires_grad or c.requires_grad):
        return torch.eye(p, dtype=HL.dtype) + HL.transpose(0, 1) @ (c.unsqueeze(-1) * HL)
    return gram(c.clamp_min(0.0).sqrt().unsqueeze(-1) * HL) + torch.eye(p, dtype=HL.dtype)


def gram(Y: Tensor) -> Tensor:
    """``Y^T Y`` (symmetric) of a float64 ``(m, r)`` tensor by one BLAS ``dsyrk`` (no autograd)."""
    Yc = Y.detach().contiguous()
    # a C-ordered (m, r) array is the Fortran-ordered (r, m) Y^T: dsyrk gives Y^T Y in the
    # lower triangle of a zero-initialised array
    low = torch.from_numpy(dsyrk(1.0, Yc.numpy().T, trans=0, lower=1))
    return low + low.transpose(0, 1) - torch.diag(torch.diagonal(low))


def whitened_precision(L: Tensor, winners: Tensor, losers: Tensor, c: Tensor) -> Tensor:
    """``B = I + L^T C L`` computed as ``I + (H L)^T diag(c) (H L)`` where the rows of ``H L``
    are ``h_n^T L = L[x_n^+] - L[x_n^-]``: one ``O(m p^2)`` product instead of two ``O(p^3)``."""
    return precision_from_rows(L[winners] - L[losers], c)


def objective(
    v: Tensor,
    L: Tensor,
    winners: Tensor,
    losers: Tensor,
    z_limit: float | None,
    ordinal: Ordinal | None = None,
) -> Tensor:
    """``S`` of paper Sec. 4 ("Posterior") in whitened form: ``-log p(D | L v) + 0.5 v^T v``."""
    t = probit_terms(L @ v, winners, losers, z_limit, ordinal)
    return -t.log_cdf.sum() + 0.5 * (v * v).sum()


def newton_step(
    v: Tensor,
    L: Tensor,
    winners: Tensor,
    losers: Tensor,
    z_limit: float | None,
    ordinal: Ordinal | None = None,
) -> tuple[Tensor, Tensor, Tensor]:
    """One full Newton step on ``S(v)`` (on the clamped gradient equation if ``z_limit``);
    returns ``(v_new, gradient of S at v, chol(B))``.

    ``v_new = B^{-1} L^T (C f + grad log p(D | f))`` with ``f = L v`` and ``B = I + L^T C L``.
    Differentiable in ``L`` (hence in the kernel hyperparameters) and in ``v``.
    """
    f = L @ v
    t = probit_terms(f, winners, losers, z_limit, ordinal)
    c = hessian_weights(t, jacobian=True)
    HL = L[winners] - L[losers]  # rows h_n^T L
    LB = torch.linalg.cholesky(precision_from_rows(HL, c))
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
    ordinal: Ordinal | None = None,
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
            return objective(vv, L, winners, losers, None, ordinal)
        t = probit_terms(L @ vv, winners, losers, z_limit)
        g = vv - (L[winners] - L[losers]).transpose(0, 1) @ (t.hazard / SQRT2)
        return (g * g).sum()

    m = merit(v)
    for it in range(1, max_iter + 1):
        v_new, _, _ = newton_step(v, L, winners, losers, z_limit, ordinal)
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
    v_hat: Tensor,
    L: Tensor,
    winners: Tensor,
    losers: Tensor,
    z_limit: float | None = None,
    ordinal: Ordinal | None = None,
) -> tuple[Tensor, Tensor, Tensor]:
    """Differentiable Laplace log evidence ``-S(f_hat) - 0.5 logdet(I + K C)`` (Chu &
    Ghahramani 2005, eq. 12), through ONE Newton step from the (detached) converged ``v_hat``.

    The Newton map has zero Jacobian in ``v`` at its fixed point, so the returned ``v1`` has the
    implicit-function derivative ``dv_hat / dtheta``; everything downstream (``S``, ``C(f_hat)``
    in the log-determinant) then has exact first derivatives w.r.t. the hyperparameters in ``L``.
    Returns ``(log_evidence, v1, chol(B) at v1)``.
    """
    v1, _, _ = newton_step(v_hat.detach(), L, winners, losers, z_limit, ordinal)
    f1 = L @ v1
    t = probit_terms(f1, winners, losers, z_limit, ordinal)
    S = -t.log_cdf.sum() + 0.5 * (v1 * v1).sum()
    B = whitened_precision(L, winners, losers, hessian_weights(t))
    LB = torch.linalg.cholesky(B)
    logdet_B = 2.0 * torch.log(torch.diagonal(LB)).sum()
    return -S.clamp_min(0.0) - 0.5 * logdet_B, v1, LB


def hessian_weight_slope(t: ProbitTerms) -> Tensor:
    """``dc_n / dz_n`` of the weights of eq. (8): with ``h = phi(z) / Phi(z)`` and
    ``dh/dz = -h (z + h)``, ``c = 0.5 h (h + z)`` gives ``dc/dz = 0.5 h (1 - (z + h)(z + 2h))``.
    Zero where BoTorch's clamp is active (the clamped ``c`` is constant there)."""
    if t.weight_slope is not None:
        return t.weight_slope
    slope = probit_weight_slope(t.z, t.hazard)
    return torch.where(t.active, slope, torch.zeros_like(slope))


def _scatter_rows(Y: Tensor, winners: Tensor, losers: Tensor, p: int) -> Tensor:
    """``H^T Y`` for the duel matrix ``H`` (row n = ``e_{x_n^+} - e_{x_n^-}``), ``Y`` ``(m, r)``."""
    out = torch.zeros(p, Y.shape[1], dtype=Y.dtype)
    return out.index_add(0, winners, Y).index_add(0, losers, -Y)


@torch.no_grad()
def log_evidence_and_kernel_gradient(
    v_hat: Tensor,
    L: Tensor,
    winners: Tensor,
    losers: Tensor,
    z_limit: float | None = None,
    ordinal: Ordinal | None = None,
) -> tuple[Tensor, Tensor, Tensor]:
    """Laplace log evidence ``E = -S(f_hat) - 0.5 logdet(I + K C)`` (Chu & Ghahramani 2005,
    eq. 12) and its analytic gradient ``G = dE/dK`` (symmetric ``(p, p)``, ``dE = tr(G dK)``),
    the value-and-gradient counterpart of :func:`log_evidence` without autograd.

    Rasmussen & Williams (2006) Alg. 5.1 generalised to the non-diagonal ``C = H^T diag(c) H``
    of eq. (8) (and to BoTorch's clamp of ``z``):

    * explicit part ``0.5 alpha alpha^T - 0.5 A`` with ``alpha = K^{-1} f_hat`` and
      ``A = C (I + K C)^{-1} = H^T (diag(c) - diag(c) Z^T Z diag(c)) H``,
      ``Z = L_B^{-1} (H L)^T`` (Woodbury, no inverse of ``C``);
    * implicit part through ``f_hat``: ``df_hat = (I + K C_J)^{-1} dK alpha`` (``C_J`` = the
      Jacobian weights, :func:`hessian_weights` with ``jacobian=True``), so it adds
      ``sym(alpha b^T)`` with ``b = (I + C_J K)^{-1} u = u - C_J L B_J^{-1} L^T u`` and
      ``u = dE/df_hat = -dS/df_hat - 0.5 H^T (c' * diag(H Sigma H^T)) / sqrt(2)``, where
      ``Sigma = L B^{-1} L^T`` and ``c'`` is :func:`hessian_weight_slope`. ``dS/df_hat`` is
      zero for the exact probit and ``H^T (g * clamped)`` with BoTorch's clamp
      (``g = hazard / sqrt(2)``, since ``K^{-1} f_hat = H^T g`` at the fixed point).

    As in :func:`log_evidence`, one Newton step from ``v_hat`` gives ``v1`` where ``S`` is
    evaluated; for the exact probit (``B_J = B``) ``B`` is factored once, at ``v_hat``, which is
    accurate to ``O(|v1 - v_hat|)`` (tiny at a converged ``v_hat``). Returns
    ``(log_evidence, v1, G)``.
    """
    p = L.shape[0]
    if z_limit is None:
        # B_J = B: factor once at v_hat, take the Newton step with it, and evaluate logdet and
        # the gradient there (v_hat is converged, so v1 - v_hat and its effect are O(tol^2)).
        f0 = L @ v_hat
        t = probit_terms(f0, winners, losers, None, ordinal)
        c = hessian_weights(t)
        HL = L[winners] - L[losers]
        LB = LB_J = torch.linalg.cholesky(precision_from_rows(HL, c))
        rhs = HL.transpose(0, 1) @ (c * (f0[winners] - f0[losers]) + t.hazard / SQRT2)
        v1 = torch.cholesky_solve(rhs.unsqueeze(-1), LB).squeeze(-1)
        log_cdf = probit_terms(L @ v1, winners, losers, None, ordinal).log_cdf
    else:
        v1, _, LB_J = newton_step(v_hat, L, winners, losers, z_limit, ordinal)
        t = probit_terms(L @ v1, winners, losers, z_limit, ordinal)
        c = hessian_weights(t)
        HL = L[winners] - L[losers]
        LB = torch.linalg.cholesky(precision_from_rows(HL, c))
        log_cdf = t.log_cdf
    S = -log_cdf.sum() + 0.5 * (v1 * v1).sum()
    value = -S.clamp_min(0.0) - torch.log(torch.diagonal(LB)).sum()

    alpha = torch.linalg.solve_triangular(L.transpose(0, 1), v1.unsqueeze(-1), upper=True)
    alpha = alpha.squeeze(-1)
    Z = torch.linalg.solve_triangular(LB, HL.transpose(0, 1), upper=False)  # (p, m)
    # explicit part: A = H^T N H with N = diag(c) - diag(c) Z^T Z diag(c)
    N = -(c.unsqueeze(-1) * gram(Z) * c)
    N = N + torch.diag(c)
    A = _scatter_rows(_scatter_rows(N, winners, losers, p).transpose(0, 1), winners, losers, p)
    # implicit part
    s = (Z * Z).sum(0)  # h_n^T Sigma h_n
    g = t.hazard / SQRT2
    weights = -0.5 * hessian_weight_slope(t) * s / SQRT2
    if z_limit is not None:
        weights = weights - torch.where(t.active, torch.zeros_like(g), g)
    u = _scatter_rows(weights.unsqueeze(-1), winners, losers, p).squeeze(-1)
    c_J = hessian_weights(t, jacobian=True)
    w = torch.cholesky_solve((L.transpose(0, 1) @ u).unsqueeze(-1), LB_J).squeeze(-1)
    b = u - _scatter_rows((c_J * (HL @ w)).unsqueeze(-1), winners, losers, p).squeeze(-1)
    ab = torch.outer(alpha, b)
    G = 0.5 * torch.outer(alpha, alpha) - 0.5 * A + 0.5 * (ab + ab.transpose(0, 1))
    return value, v1, G
