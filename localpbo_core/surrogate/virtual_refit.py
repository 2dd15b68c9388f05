"""Batched Laplace refits of the pairwise GP with one extra *virtual* duel (paper Sec. 5.1,
eq. (16) "GIPBO acquisition"; App. C.2 "Preferential GI acquisition evaluation").

For a batch of virtual datasets ``D_b = {D, (w_b > l_b)}`` that extend the fitted data by
``k`` new points ``Z_b`` (the same ``k`` for the whole batch) and one duel, this module
re-solves the Laplace MAP at the FIXED hyperparameters of a fitted
:class:`~localpbo_core.surrogate.pairwise_gp.PairwiseGPSurrogate`, for all ``b`` at once, and
returns ``tr Sigma_11(x_c | D_b)`` of paper eq. (15) "pairwise-GP Jacobian variance" at a query
point ``x_c``.

Everything is done in *duel space* (dimension ``m + 1``, the number of duels), exact:

* ``C = H^T D H`` (eq. (8)) with ``H`` the ``(m, P)`` duel incidence matrix (rows
  ``h_n = e_{w_n} - e_{l_n}``) and ``D = diag(c_n)``. With ``A = D^{1/2} H`` and
  ``Q = H K H^T``, Woodbury gives
  ``k_a^T (K + C^{-1})^{-1} k_b = (A k_a)^T M^{-1} (A k_b)``, ``M = I + D^{1/2} Q D^{1/2}``
  (Rasmussen & Williams 2006, Alg. 3.2 with ``W = A^T A``); no inverse of ``C`` or ``K``.
* The MAP satisfies ``f_hat = K grad log p(D | f_hat) = K H^T alpha`` with
  ``alpha_n = hazard_n / sqrt(2)``; Newton's method (R&W Alg. 3.1) keeps ``f = K H^T alpha``,
  so it runs on ``alpha`` with ``H f = Q alpha`` and ``f^T K^{-1} f = alpha^T Q alpha``:
  ``beta = D H f + hazard / sqrt(2)``, ``alpha <- beta - D^{1/2} M^{-1} D^{1/2} Q beta``.
* Warm start: ``[alpha_hat, 0]`` is EXACTLY the current MAP extended to
  ``Z`` by the posterior mean (``mu(Z) = K(Z, X) K^{-1} f_hat = K(Z, X) H^T alpha_hat``), so
  Newton only has to absorb the virtual duel (typically 3-5 iterations).
* ``Q``'s old block ``H K H^T = (H L)(H L)^T`` is shared by the whole batch; only the virtual
  duel's row differs. Newton runs in two phases: a chord phase with the old duels' weights
  frozen at the fit's MAP (then ``M = [[A, u_b], [u_b^T, gamma_b]]`` with ``A`` SHARED, so a
  solve is one shared-factor triangular solve plus a scalar Schur complement, no per-candidate
  factorisation; the fixed point is still the exact MAP), then exact Newton steps (normally
  one) whose factor ``chol(M)`` also gives the covariance. Per candidate: about one
  ``(m+1)``-Cholesky in total.

``K`` here is the fit's ``K + jitter`` (its Cholesky ``chol_K``); the new points get the
relative jitter ``surrogate.jitter``, as a full refit with fixed hyperparameters would.

"Can't tell" answers: with the ordinal likelihood of :mod:`.ordinal` (the fit's ties and
``tie_threshold``, and optionally a virtual duel that is itself a tie, ``virtual_tie``),
``log Phi``, ``hazard / sqrt(2)`` and ``c_n`` above become each row's log-likelihood, its
derivative in ``g`` and ``-d^2 log p / dg^2``; nothing else changes.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch
from torch import Tensor

from .kernel import kernel_derivatives, se_kernel_exact
from .laplace import SQRT2, probit_hazard, probit_terms_of_differences, probit_weight
from .ordinal import Ordinal
from .protocol import Surrogate


@dataclass
class VirtualFit:
    """Batched Laplace fits on extended data, in duel space (see the module docstring).

    Attributes:
        alpha: ``(B, m+1)`` MAP coefficients, ``f_hat = K_ext H^T alpha``.
        sqrt_c: ``(B, m+1)`` ``D^{1/2}`` at the MAP (eq. (8) weights).
        chol_M: ``(B, m+1, m+1)`` Cholesky of ``I + D^{1/2} Q D^{1/2}``.
        new_points: ``(B, k, d)``; winners, losers: ``(B,)`` virtual duel indices.
        iterations: Newton iterations used.
    """

    alpha: Tensor
    sqrt_c: Tensor
    chol_M: Tensor
    new_points: Tensor
    winners: Tensor
    losers: Tensor
    iterations: int


def _probit(z: Tensor) -> tuple[Tensor, Tensor]:
    """``log Phi(z)`` and the hazard ``phi(z) / Phi(z)`` (eq. (5) "likelihood", sigma_n = 1)."""
    log_cdf = torch.special.log_ndtr(z)
    return log_cdf, probit_hazard(z, log_cdf)


def _row_terms(hf: Tensor, tie: Tensor | None, threshold: float) -> tuple[Tensor, Tensor, Tensor]:
    """Per-row ``log p``, ``dlog p / dg`` and the weight ``c`` at ``g = hf`` ``(B, m+1)``:
    the paper's probit (eq. (5), weights eq. (8)) when ``tie`` is None, else the ordinal
    likelihood with the tie mask ``tie`` ``(B, m+1)``."""
    if tie is None:
        z = hf / SQRT2
        log_cdf, hazard = _probit(z)
        return log_cdf, hazard / SQRT2, probit_weight(z, hazard)
    t = probit_terms_of_differences(hf.reshape(-1), None, Ordinal(tie.reshape(-1), threshold))
    assert t.weight is not None  # an ordinal likelihood always carries its weights
    shape = hf.shape
    return t.log_cdf.reshape(shape), (t.hazard / SQRT2).reshape(shape), t.weight.reshape(shape)


def _chol_solve(b: Tensor, L: Tensor) -> Tensor:
    """``(L L^T)^{-1} b`` by two triangular solves (faster than batched ``cholesky_solve``)."""
    y = torch.linalg.solve_triangular(L, b, upper=False)
    return torch.linalg.solve_triangular(L.transpose(-1, -2), y, upper=True)


def _extended_rows(surrogate: Surrogate, new_points: Tensor, idx: Tensor) -> tuple[Tensor, Tensor]:
    """Rows ``idx_b`` of the jittered extended kernel ``K([X; Z_b], [X; Z_b])``, split into the
    ``X`` part ``(B, p)`` and the ``Z`` part ``(B, k)``."""
    X, L = surrogate.train_inputs, surrogate.chol_K
    p = X.shape[0]
    Bn, k = new_points.shape[:2]
    ls, s = surrogate.lengthscale, surrogate.outputscale
    old = idx < p
    rows_x = torch.empty(Bn, p, dtype=torch.float64)
    rows_z = torch.empty(Bn, k, dtype=torch.float64)
    if old.any():
        io = idx[old]
        rows_x[old] = L[io] @ L.transpose(0, 1)  # (K + jitter)[i, :]
        rows_z[old] = se_kernel_exact(X[io].unsqueeze(1), new_points[old], ls, s)[:, 0]
    if (~old).any():
        b = torch.nonzero(~old).flatten()
        j = idx[b] - p
        z_b = new_points[b, j]  # (nb, d)
        rows_x[b] = se_kernel_exact(z_b, X, ls, s)
        rz = se_kernel_exact(z_b.unsqueeze(1), new_points[b], ls, s)[:, 0]  # (nb, k)
        rz[torch.arange(b.shape[0]), j] += surrogate.jitter * s
        rows_z[b] = rz
    return rows_x, rows_z


@torch.no_grad()
def virtual_refit(
    surrogate: Surrogate,
    new_points: Tensor,
    winners: Tensor,
    losers: Tensor,
    tol: float = 1e-10,
    max_iter: int = 100,
    chord_iter: int = 30,
    virtual_tie: Tensor | None = None,
) -> VirtualFit:
    """Laplace MAP of ``D`` plus one virtual duel per batch element, fixed hyperparameters.

    Args:
        surrogate: a fit with the exact probit likelihood (``z_limit=None``) and
            ``eps_reg=0``.
        new_points: ``(B, k, d)`` points appended to ``surrogate.train_inputs`` (``k >= 0``);
            they must not coincide with training points (no consolidation is done here).
        winners, losers: ``(B,)`` long indices of the virtual duel into ``[X; Z_b]``.
        tol: Newton stops when every change of ``H f`` is below ``tol * (1 + |H f|_inf)``.
        max_iter: exact Newton iteration cap.
        chord_iter: cap of the chord phase (it also stops once it contracts by less than 4x
            per iteration).
        virtual_tie: ``(B,)`` bool, True where the virtual duel is a "can't tell" answer
            (needs ``surrogate.tie_threshold > 0``); None: all decisive.
    """
    if surrogate.z_limit is not None:
        raise ValueError("virtual_refit: only the exact probit likelihood (z_limit=None)")
    if surrogate.eps_reg != 0:
        raise ValueError("virtual_refit: only eps_reg=0 (C_hat = C)")
    X = surrogate.train_inputs
    p, d = X.shape
    if new_points.ndim != 3 or new_points.shape[2] != d:
        raise ValueError(f"new_points must have shape (B, k, {d}), got {tuple(new_points.shape)}")
    Bn, k = new_points.shape[:2]
    if winners.shape != (Bn,) or losers.shape != (Bn,):
        raise ValueError(f"winners and losers must have shape ({Bn},)")
    P = p + k
    if ((winners == losers) | (winners < 0) | (losers < 0) | (winners >= P) | (losers >= P)).any():
        raise ValueError("virtual duels must be between two distinct points of [X; Z]")
    wo, lo = surrogate.winners, surrogate.losers
    m = wo.shape[0]
    eps = float(surrogate.tie_threshold)
    tie_rows: Tensor | None = None
    if virtual_tie is not None and bool(virtual_tie.any()) and eps <= 0:
        raise ValueError("virtual_refit: a virtual tie needs tie_threshold > 0")
    if eps > 0:
        vt = torch.zeros(Bn, dtype=torch.bool) if virtual_tie is None else virtual_tie
        tie_rows = torch.cat([surrogate.tie.expand(Bn, m), vt.reshape(Bn, 1)], dim=1)
    L = surrogate.chol_K
    HL = L[wo] - L[lo]
    # --- Q = H K H^T: shared old block, per-element virtual row
    rwx, rwz = _extended_rows(surrogate, new_points, winners)
    rlx, rlz = _extended_rows(surrogate, new_points, losers)
    rx, rz = rwx - rlx, rwz - rlz  # row h_new^T K_ext, split (B, p), (B, k)
    q = rx[:, wo] - rx[:, lo]  # (B, m)
    r_full = torch.cat([rx, rz], dim=1)
    bi = torch.arange(Bn)
    q_nn = r_full[bi, winners] - r_full[bi, losers]
    Qoo = HL @ HL.transpose(0, 1)  # old block of Q, shared
    Q = torch.empty(Bn, m + 1, m + 1, dtype=torch.float64)
    Q[:, :m, :m] = Qoo
    Q[:, :m, m] = q
    Q[:, m, :m] = q
    Q[:, m, m] = q_nn
    # --- warm start: the current MAP extended by the posterior mean (exact, see docstring)
    g_fit = (surrogate.utility[wo] - surrogate.utility[lo]).unsqueeze(0)
    _, d1_fit, c_fit = _row_terms(g_fit, None if tie_rows is None else tie_rows[:1, :m], eps)
    alpha = torch.zeros(Bn, m + 1, dtype=torch.float64)
    alpha[:, :m] = d1_fit[0]

    def state(a: Tensor) -> tuple[Tensor, Tensor, Tensor, Tensor]:
        ao, an = a[:, :m], a[:, m]
        hf = torch.cat(
            [ao @ Qoo + q * an.unsqueeze(-1), ((q * ao).sum(-1) + q_nn * an).unsqueeze(-1)], 1
        )  # H f = Q a
        log_lik, d1, c = _row_terms(hf, tie_rows, eps)
        obj = -log_lik.sum(-1) + 0.5 * (a * hf).sum(-1)  # S(f), f^T K^-1 f = a^T Q a
        return hf, d1, c, obj

    def backtrack(
        a: Tensor, step: Tensor, obj: Tensor
    ) -> tuple[Tensor, Tensor, Tensor, Tensor, Tensor]:
        t = torch.ones(Bn, dtype=torch.float64)
        for _ in range(40):  # per-element backtracking on the convex objective S
            cand = a + t.unsqueeze(-1) * step
            hf_c, d1_c, c_c, obj_c = state(cand)
            bad = ~(torch.isfinite(obj_c) & (obj_c <= obj + 1e-12 * obj.abs()))
            if not bad.any():
                break
            t = torch.where(bad, 0.5 * t, t)
        return cand, hf_c, d1_c, c_c, obj_c

    def converged(hf_new: Tensor, hf_old: Tensor) -> bool:
        change = (hf_new - hf_old).abs().amax(-1)
        return bool((change <= tol * (1.0 + hf_new.abs().amax(-1))).all())

    hf, d1, c, obj = state(alpha)
    # --- chord phase: Newton with the old duels' weights frozen at the fit's MAP, so that
    # M = [[A, u_b], [u_b^T, gamma_b]] has a SHARED block A = I + D0^1/2 Q_oo D0^1/2 and each
    # solve is one shared-factor solve plus a scalar Schur complement. Its fixed point is the
    # MAP (any PD weight matrix gives a convergent, line-searched descent step).
    sc0 = c_fit[0].sqrt()
    LA = torch.linalg.cholesky(
        torch.eye(m, dtype=torch.float64) + sc0.unsqueeze(-1) * Qoo * sc0.unsqueeze(-2)
    )
    sq = sc0 * q  # (B, m)
    Wq = _chol_solve(sq.transpose(0, 1), LA).transpose(0, 1)  # A^-1 (D0^1/2 q_b)
    sqWq = (sq * Wq).sum(-1)
    prev_change = torch.inf
    for _ in range(chord_iter):
        c_new = c[:, m]
        scn = c_new.sqrt()
        sct = torch.cat([sc0.expand(Bn, m), scn.unsqueeze(-1)], 1)
        beta = sct * sct * hf + d1
        qb, _, _, _ = state(beta)
        r = sct * qb
        Ainv_ro = _chol_solve(r[:, :m].transpose(0, 1), LA).transpose(0, 1)
        sigma = 1.0 + c_new * (q_nn - sqWq)
        yn = (r[:, m] - scn * (sq * Ainv_ro).sum(-1)) / sigma
        yo = Ainv_ro - (scn * yn).unsqueeze(-1) * Wq
        step = beta - sct * torch.cat([yo, yn.unsqueeze(-1)], 1) - alpha
        hf_old = hf
        alpha, hf, d1, c, obj = backtrack(alpha, step, obj)
        if converged(hf, hf_old):
            break
        change = float((hf - hf_old).abs().max())
        if change > 0.25 * prev_change:  # slow contraction: leave the rest to exact Newton
            break
        prev_change = change
    # --- exact Newton polish (normally one step); its last factor gives the covariance

    def chol_m(c: Tensor) -> tuple[Tensor, Tensor]:
        sc = c.sqrt()  # eq. (8) weights
        M = Q * sc.unsqueeze(-2)
        M.mul_(sc.unsqueeze(-1)).diagonal(dim1=-2, dim2=-1).add_(1.0)
        return sc, torch.linalg.cholesky(M)

    it = 0
    sc, LM = chol_m(c)
    for it in range(1, max_iter + 1):  # noqa: B007 - reported in VirtualFit
        beta = c * hf + d1
        qb = (Q @ beta.unsqueeze(-1)).squeeze(-1)
        corr = _chol_solve((sc * qb).unsqueeze(-1), LM).squeeze(-1)
        step = beta - sc * corr - alpha
        hf_old = hf
        alpha, hf, d1, c, obj = backtrack(alpha, step, obj)
        if converged(hf, hf_old):
            # Newton converges quadratically: the factor at the previous iterate differs from
            # the one at the MAP by O(change), below the requested tolerance.
            break
        sc, LM = chol_m(c)
    return VirtualFit(
        alpha=alpha,
        sqrt_c=sc,
        chol_M=LM,
        new_points=new_points,
        winners=winners,
        losers=losers,
        iterations=it,
    )


@torch.no_grad()
def gradient_covariance_trace(surrogate: Surrogate, fit: VirtualFit, x: Tensor) -> Tensor:
    """``tr Sigma_11(x | D_b)`` of eq. (15) "pairwise-GP Jacobian variance" for every batch element:

    ``tr(s Lambda) - ||M^{-1/2} D^{1/2} H k_1||_F^2`` with ``k_1 = grad_x K(x, [X; Z_b])``
    (Woodbury form of the module docstring). ``x`` is ``(d,)``; returns ``(B,)``.
    """
    ls, s = surrogate.lengthscale, surrogate.outputscale
    X = surrogate.train_inputs
    p = X.shape[0]
    xb = x.reshape(1, -1)
    _, k1x = kernel_derivatives(xb, X, ls, s, 1)  # (1, p, d)
    _, k1z = kernel_derivatives(xb, fit.new_points, ls, s, 1)  # (B, k, d)
    k1x = k1x[0]
    wo, lo = surrogate.winners, surrogate.losers
    Bn = fit.alpha.shape[0]
    k1_full = torch.cat([k1x.expand(Bn, p, k1x.shape[1]), k1z], dim=1)  # (B, P, d)
    bi = torch.arange(Bn)
    g_new = k1_full[bi, fit.winners] - k1_full[bi, fit.losers]  # (B, d)
    G = torch.cat([(k1x[wo] - k1x[lo]).expand(Bn, -1, -1), g_new.unsqueeze(1)], dim=1)
    G = fit.sqrt_c.unsqueeze(-1) * G
    V = torch.linalg.solve_triangular(fit.chol_M, G, upper=False)
    return s * ls.pow(-2).sum() - (V * V).sum((-2, -1))
