"""The exact preference posterior of a GP under the probit duel likelihood (a skew GP).

Model (the probit likelihood of paper Sec. 4, eq. (5) "likelihood", written with an auxiliary
variable). Let ``f`` be the latent utility at the ``n`` duelled points ``X``, a priori
``f ~ N(0, K)`` with the paper's kernel (paper Sec. 4 "Prior", App. D.2:
``k(x, x') = s exp(-0.5 sum_i (x_i - x'_i)^2 / l_i^2)``). Duel ``k`` (winner ``w_k``, loser
``l_k``) is observed through

    y_k = f_{w_k} - f_{l_k} + eps_k > 0,        eps_k ~ N(0, 2 sigma^2) independent,

so ``P(duel k | f) = Phi((f_{w_k} - f_{l_k}) / (sqrt(2) sigma))``: exactly paper eq. (5) with
the paper's preference noise ``sigma_n = sigma``. As in the pairwise GP surrogate
(:mod:`.laplace`, BoTorch's convention) ``sigma = 1`` by default, i.e. noise variance ``2`` per
duel. With ``H`` the ``m x n`` duel matrix (``H[k, w_k] = 1``, ``H[k, l_k] = -1``) define

    g = H f + eps ~ N(0, M),        M = H K H^T + 2 sigma^2 I   (m x m, always positive definite).

Observing every duel is the event ``{g > 0}``, hence

* the posterior of ``g`` is the normal ``N(0, M)`` truncated to the positive orthant;
* ``f | g`` is Gaussian (ordinary GP regression on the noisy differences ``g``):
  ``E[f | g] = K H^T M^{-1} g``, ``Cov[f | g] = K - K H^T M^{-1} H K``, and for any point
  ``x``: ``mu_g(x) = k(x, X) H^T M^{-1} g``,
  ``var_g(x) = s - k(x, X) H^T M^{-1} H k(X, x)``;
* the posterior of ``f`` (the mixture over ``g``) is a unified skew-normal, so the GP
  posterior is a skew GP (Benavoli, Azzimonti and Piga 2020; Takeno et al. 2023).

Sampling is therefore exact up to the Markov chain: draw ``g`` from the truncated normal,
then ``f | g`` in closed form (pathwise: ``f = f0 + K H^T M^{-1} (g - H f0 - eps0)`` with
``f0 ~ N(0, K)``, ``eps0 ~ N(0, 2 sigma^2 I)``, which needs no inverse of ``K``).

Sampler for ``g``: linear elliptical slice sampling (LinESS) of

    Alexandra Gessner, Oindrila Kanjilal, Philipp Hennig. *Integrals over Gaussians under
    linear domain constraints*. AISTATS 2020,

which is also what Takeno et al. compare against Gibbs sampling in

    Shion Takeno, Masahiro Nomura, Masayuki Karasuyama. *Towards practical preferential
    Bayesian optimization with skew Gaussian processes*. ICML 2023.

One step from a feasible state ``g``: draw ``nu ~ N(0, M)`` (``nu = L_M z``, ``L_M`` the
Cholesky factor of ``M``), and move to ``g cos t + nu sin t`` with the angle ``t`` uniform on
the part of the ellipse inside the domain. Elliptical slice sampling with an indicator
likelihood leaves ``N(0, M)`` restricted to the domain invariant (the rotation
``(g, nu) -> (g cos t + nu sin t, -g sin t + nu cos t)`` preserves ``N(0, M) x N(0, M)`` and the
angle is drawn uniformly on the slice, i.e. the slice is sampled exactly, without shrinking).
For the orthant the slice has a closed form: coordinate ``k`` is
``g_k cos t + nu_k sin t = r_k cos(t - phi_k)`` with ``phi_k = atan2(nu_k, g_k)``, in
``(-pi/2, pi/2)`` because ``g_k > 0``, so it is positive exactly on the half circle
``|t - phi_k| < pi/2``. Every such arc contains ``t = 0``, so their intersection is the single
interval ``(max_k phi_k - pi/2, min_k phi_k + pi/2)`` (the general LinESS bookkeeping of
Gessner et al. for ``m`` arbitrary half-spaces reduces to two reductions here). A proposal whose
computed ``g`` is not strictly positive (possible only by rounding at the very edge of the
interval) is redrawn, so every state satisfies ``g > 0`` exactly in floating point.

Warm start (:meth:`DuelPosteriorChain.update`): the constraint set ``{g > 0}`` does not depend
on the kernel, so after new hyperparameters the old state is still feasible and the chain
simply continues on the new ``M``. When duels are appended, the state is extended by drawing
each new ``g_k`` from its conditional ``N(0, M)`` given the earlier coordinates, truncated to
``g_k > 0`` (with ``M = L L^T``: ``g_k = sum_{j<k} L_kj u_j + L_kk u_k`` with ``u = L^{-1} g``,
so ``u_k`` is a standard normal truncated to ``u_k > -sum_{j<k} L_kj u_j / L_kk``). The extended
state satisfies every constraint; the following LinESS steps make it a draw of the new
posterior. The same sequential draw, started from no duel, is the cold start. When only duels
and points are appended and the hyperparameters are unchanged, ``K`` and the Cholesky factor
of ``M`` are extended by the new rows (``O(m^2)`` per duel) instead of refactorised.

"Can't tell" answers (the ordinal likelihood of :mod:`.ordinal`, Chu & Ghahramani 2005, with
the indifference threshold ``eps > 0``): a decisive duel is the event ``g_k >= eps`` and a tie
the two-sided truncation ``|g_k| < eps``, i.e. two linear constraints; the posterior of ``g``
is ``N(0, M)`` restricted to the intersection of these slabs and half-spaces, and ``f | g`` is
unchanged. LinESS then needs the general bookkeeping: a decisive coordinate
``r_k cos(t - phi_k) > eps`` holds on the arc ``|t - phi_k| < arccos(eps / r_k)``, which
contains ``t = 0``, so the decisive constraints still give one interval ``I`` (at ``eps = 0``
exactly the orthant's). A tie removes the two arcs where ``|r_k cos(t - phi_k)| >= eps``; the
angle is drawn uniformly on ``I`` and, while a tie is violated, ``I`` is shrunk towards 0 (the
shrinkage of elliptical slice sampling, Murray, Adams and MacKay 2010, which leaves the
restricted normal invariant). The sequential extension draws a tie's coordinate from its
conditional truncated to ``(-eps, eps)``.

All randomness comes from the ``numpy.random.Generator`` passed in; nothing touches a global
random state.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import scipy.linalg
from scipy.special import log_ndtr, ndtri_exp

#: Preference noise ``sigma`` of the probit likelihood (BoTorch's convention, as the surrogate).
DEFAULT_NOISE_STD = 1.0
#: Redraws of the angle of one LinESS step before the step keeps its current state.
_MAX_ANGLE_DRAWS = 64
#: LinESS steps whose random directions are drawn in one block.
_BLOCK_STEPS = 256
#: Shrinkage draws of one LinESS step with ties before the step keeps its current state.
_MAX_SHRINK_DRAWS = 200


def se_kernel_np(
    x1: np.ndarray, x2: np.ndarray, lengthscale: np.ndarray, outputscale: float
) -> np.ndarray:
    """``k(x1_i, x2_j)`` of the paper's ARD squared-exponential kernel, ``(n1, n2)``, from
    explicit differences: every entry depends only on its two points, bit for bit, whatever
    else is in the batch (so an incrementally grown kernel matrix equals a fresh one)."""
    diff = (x1[:, None, :] - x2[None, :, :]) / lengthscale
    return outputscale * np.exp(-0.5 * np.einsum("ijk,ijk->ij", diff, diff))


def duel_matrix(winners: np.ndarray, losers: np.ndarray, n: int) -> np.ndarray:
    """``H`` ``(m, n)``: ``H[k, winners[k]] = 1``, ``H[k, losers[k]] = -1``."""
    m = len(winners)
    H = np.zeros((m, n))
    H[np.arange(m), winners] = 1.0
    H[np.arange(m), losers] = -1.0
    return H


def truncated_standard_normal_above(a: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Draws of ``u ~ N(0, 1)`` conditioned on ``u > a`` (elementwise), by inversion in log
    space: ``u = -Phi^{-1}(V Phi(-a))``, ``V ~ U(0, 1)``; accurate for any ``a`` (no underflow
    in the far tail). The result is strictly greater than ``a``."""
    a = np.asarray(a, dtype=np.float64)
    v = rng.random(a.shape)
    u = -ndtri_exp(np.log(v) + log_ndtr(-a))
    return np.maximum(u, np.nextafter(a, np.inf))


def truncated_standard_normal_between(
    a: np.ndarray, b: np.ndarray, rng: np.random.Generator
) -> np.ndarray:
    """Draws of ``u ~ N(0, 1)`` conditioned on ``a < u < b`` (elementwise, ``a < b``) by
    inversion in log space on the side of the Gaussian where the interval lies (the draw is
    mirrored when ``a + b > 0``), accurate in the far tails."""
    a = np.asarray(a, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    flip = a + b > 0.0
    lo = np.where(flip, -b, a)
    hi = np.where(flip, -a, b)
    v = rng.random(a.shape)
    log_hi = log_ndtr(hi)
    w = np.exp(log_ndtr(lo) - log_hi)  # Phi(lo) / Phi(hi) in [0, 1)
    x = ndtri_exp(log_hi + np.log(w + v * (1.0 - w)))
    x = np.minimum(np.maximum(x, np.nextafter(lo, np.inf)), np.nextafter(hi, -np.inf))
    return np.where(flip, -x, x)


def _feasible(out: np.ndarray, threshold: float, tie: np.ndarray | None) -> np.ndarray:
    """Rows of ``out`` ``(C, m)`` inside every constraint: ``g > eps`` (decisive), ``|g| < eps``
    (tie)."""
    if tie is None:
        return np.asarray((out > threshold).all(axis=1))
    return np.asarray(np.where(tie, np.abs(out) < threshold, out > threshold).all(axis=1))


def _lin_ess_step_ordinal(
    g: np.ndarray,
    nu: np.ndarray,
    u: np.ndarray,
    rng: np.random.Generator,
    threshold: float,
    tie: np.ndarray,
) -> np.ndarray:
    """LinESS with decisive constraints ``g_k > eps`` and ties ``|g_k| < eps`` (module
    docstring): the exact interval of the decisive arcs, then shrinkage towards 0 for ties."""
    dec = ~tie
    phi = np.arctan2(nu, g)
    r = np.hypot(g, nu)
    half = np.arccos(np.clip(threshold / np.maximum(r, 1e-300), -1.0, 1.0))
    if dec.any():
        lo = (phi[:, dec] - half[:, dec]).max(axis=1)
        hi = (phi[:, dec] + half[:, dec]).min(axis=1)
    else:
        lo = np.full(g.shape[0], -math.pi)
        hi = np.full(g.shape[0], math.pi)
    lo = np.minimum(lo, 0.0)
    hi = np.maximum(hi, 0.0)
    out = g.copy()
    todo = np.arange(g.shape[0])
    t = lo + (hi - lo) * u
    for _ in range(_MAX_SHRINK_DRAWS):
        prop = g[todo] * np.cos(t)[:, None] + nu[todo] * np.sin(t)[:, None]
        ok = _feasible(prop, threshold, tie)
        out[todo[ok]] = prop[ok]
        keep = ~ok
        todo, t = todo[keep], t[keep]
        if todo.size == 0:
            break
        neg = t < 0.0
        lo[todo[neg]] = t[neg]
        hi[todo[~neg]] = t[~neg]
        t = lo[todo] + (hi[todo] - lo[todo]) * rng.random(todo.size)
    return out  # a chain still in ``todo`` keeps its state (the angle t = 0)


def lin_ess_step(
    g: np.ndarray,
    chol_M: np.ndarray,
    rng: np.random.Generator,
    nu: np.ndarray | None = None,
    u: np.ndarray | None = None,
    threshold: float = 0.0,
    tie: np.ndarray | None = None,
) -> np.ndarray:
    """One LinESS step for ``N(0, M)`` restricted to ``{g > 0}`` (see the module docstring).

    Args:
        g: ``(C, m)`` current states of ``C`` independent chains, every entry > 0.
        chol_M: ``(m, m)`` lower Cholesky factor of ``M``.
        rng: source of every random draw.
        nu: optional pre-drawn ``(C, m)`` rows ``~ N(0, M)`` (else drawn from ``rng``).
        u: optional pre-drawn ``(C,)`` uniforms for the angles (else drawn from ``rng``).
        threshold, tie: the ordinal constraints (``g_k > eps``, ties ``|g_k| < eps``; ``tie``
            ``(m,)`` bool); the default is the orthant ``g > 0``.

    Returns:
        ``(C, m)`` new states, every entry > 0 (inside every constraint).
    """
    C = g.shape[0]
    if nu is None:
        nu = rng.standard_normal(g.shape) @ chol_M.T  # rows ~ N(0, M)
    if u is None:
        u = np.asarray(rng.random(C))
    if threshold > 0.0 or tie is not None:
        ties = np.zeros(g.shape[1], dtype=bool) if tie is None else tie
        return _lin_ess_step_ordinal(g, nu, u, rng, threshold, ties)
    phi = np.arctan2(nu, g)  # in (-pi/2, pi/2) since g > 0
    lo = phi.max(axis=1) - 0.5 * math.pi
    width = phi.min(axis=1) + 0.5 * math.pi - lo
    t = lo + width * u
    out = g * np.cos(t)[:, None] + nu * np.sin(t)[:, None]
    bad = ~(out > 0.0).all(axis=1)
    if not bad.any():
        return out
    # Only by rounding at the very edge of the interval: redraw those angles.
    out[bad] = g[bad]
    todo = np.flatnonzero(bad)
    for _ in range(_MAX_ANGLE_DRAWS):
        t = lo[todo] + width[todo] * rng.random(todo.size)
        prop = g[todo] * np.cos(t)[:, None] + nu[todo] * np.sin(t)[:, None]
        ok = (prop > 0.0).all(axis=1)
        out[todo[ok]] = prop[ok]
        todo = todo[~ok]
        if todo.size == 0:
            break
    return out  # a chain still in ``todo`` keeps its state (the angle t = 0)


def sequential_extension(
    g: np.ndarray,
    chol_M: np.ndarray,
    start: int,
    rng: np.random.Generator,
    threshold: float = 0.0,
    tie: np.ndarray | None = None,
) -> np.ndarray:
    """Extend states ``g`` ``(C, start)`` to ``(C, m)`` by drawing coordinates
    ``start..m-1`` one by one from their conditionals under ``N(0, M)`` truncated to > 0
    (``chol_M`` is the ``(m, m)`` factor of the extended ``M``); with the ordinal constraints,
    to ``> eps`` (decisive) or ``(-eps, eps)`` (``tie[k]``)."""
    C = g.shape[0]
    m = chol_M.shape[0]
    u = np.zeros((C, m))
    if start > 0:
        u[:, :start] = scipy.linalg.solve_triangular(
            chol_M[:start, :start], g.T, lower=True, check_finite=False
        ).T
    out = np.zeros((C, m))
    out[:, :start] = g
    for k in range(start, m):
        cond_mean = u[:, :k] @ chol_M[k, :k]
        if tie is not None and tie[k]:
            a = (-threshold - cond_mean) / chol_M[k, k]
            b = (threshold - cond_mean) / chol_M[k, k]
            u[:, k] = truncated_standard_normal_between(a, b, rng)
            out[:, k] = np.clip(
                cond_mean + chol_M[k, k] * u[:, k],
                np.nextafter(-threshold, 0.0),
                np.nextafter(threshold, 0.0),
            )
            continue
        a = (threshold - cond_mean) / chol_M[k, k] if threshold > 0.0 else -cond_mean / chol_M[k, k]
        u[:, k] = truncated_standard_normal_above(a, rng)
        gk = cond_mean + chol_M[k, k] * u[:, k]
        # strictly positive by construction; guard the rounding of the sum
        out[:, k] = np.where(gk > threshold, gk, np.nextafter(threshold, np.inf))
    return out


@dataclass(frozen=True)
class ConditionedGP:
    """The GP of ``f`` given one hallucination ``g`` (see the module docstring):
    ``mu(x) = k(x, X) alpha``, ``var(x) = s - k(x, X) Q k(X, x)`` with ``alpha = H^T M^{-1} g``
    and ``Q = H^T M^{-1} H``."""

    X: np.ndarray
    lengthscale: np.ndarray
    outputscale: float
    alpha: np.ndarray
    Q: np.ndarray

    def _cross(self, x: np.ndarray) -> np.ndarray:
        """``k(x, X)`` ``(N, n)`` by one matrix product (``|a|^2 + |b|^2 - 2 a.b`` of the
        scaled points): no ``(N, n, d)`` temporary."""
        a = x / self.lengthscale
        b = self.X / self.lengthscale
        sq = (a * a).sum(1)[:, None] + (b * b).sum(1)[None, :] - 2.0 * a @ b.T
        return self.outputscale * np.exp(-0.5 * np.maximum(sq, 0.0))

    def mean_var(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Posterior mean and variance ``(N,)`` at points ``x`` ``(N, d)``."""
        b = self._cross(x)
        var = self.outputscale - np.einsum("ij,ij->i", b @ self.Q, b)
        return b @ self.alpha, np.maximum(var, 1e-12 * self.outputscale)

    def mean_var_grad(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Mean, variance ``(N,)`` and their gradients ``(N, d)`` in ``x``.

        With ``b_j = k(x, X_j)``: ``db_j/dx = -b_j (x - X_j) / l^2``, so for weights ``w_j``
        ``sum_j w_j db_j/dx = -(x sum_j w_j b_j - sum_j w_j b_j X_j) / l^2``: the mean has
        ``w = alpha``, the variance ``w = -2 Q b``."""
        inv_l2 = self.lengthscale**-2
        b = self._cross(x)
        Qb = b @ self.Q
        raw_var = self.outputscale - np.einsum("ij,ij->i", Qb, b)
        floor = 1e-12 * self.outputscale
        var = np.maximum(raw_var, floor)
        wm = b * self.alpha  # (N, n)
        dmu = -(x * wm.sum(1)[:, None] - wm @ self.X) * inv_l2
        wv = Qb * b
        dvar = 2.0 * (x * wv.sum(1)[:, None] - wv @ self.X) * inv_l2
        dvar = np.where((raw_var > floor)[:, None], dvar, 0.0)
        return b @ self.alpha, var, dmu, dvar


class DuelPosteriorChain:
    """LinESS Markov chain(s) on the skew-GP posterior of a growing set of duels.

    Call :meth:`update` with all points and duels so far (and the kernel hyperparameters),
    then :meth:`run` to advance the chain; :attr:`g` is the current hallucination of the noisy
    utility differences, :meth:`conditioned_gp` the GP of ``f`` given it and
    :meth:`sample_latent` a draw of ``f`` at the points.

    Args:
        noise_std: ``sigma`` of the likelihood (noise variance ``2 sigma^2`` per duel).
        num_chains: independent chains run side by side (HB-EI uses one).
        tie_threshold: the indifference threshold ``eps >= 0`` of the ordinal likelihood
            (decisive duels ``g_k > eps``, ties ``|g_k| < eps``; module docstring).
    """

    def __init__(
        self, noise_std: float = DEFAULT_NOISE_STD, num_chains: int = 1, tie_threshold: float = 0.0
    ) -> None:
        if not math.isfinite(tie_threshold) or tie_threshold < 0:
            raise ValueError(f"tie_threshold must be finite and >= 0, got {tie_threshold}")
        self.tie_threshold = float(tie_threshold)
        self.tie: np.ndarray | None = None
        if not math.isfinite(noise_std) or noise_std <= 0:
            raise ValueError(f"noise_std must be finite and positive, got {noise_std}")
        if num_chains < 1:
            raise ValueError(f"num_chains must be >= 1, got {num_chains}")
        self.noise_var = 2.0 * noise_std**2
        self.num_chains = int(num_chains)
        self.X = np.empty((0, 0))
        self.winners = np.empty(0, dtype=np.int64)
        self.losers = np.empty(0, dtype=np.int64)
        self.lengthscale = np.empty(0)
        self.outputscale = float("nan")
        self.K = np.empty((0, 0))
        self.chol_M = np.empty((0, 0))
        self.g = np.empty((self.num_chains, 0))
        #: Counters for profiling: full factorisations and one-row extensions of ``M``.
        self.full_factorizations = 0
        self.extended_rows = 0

    # ------------------------------------------------------------------ model
    @property
    def num_duels(self) -> int:
        """``m``, the number of duels the chain currently targets."""
        return int(self.winners.shape[0])

    def update(
        self,
        X: np.ndarray,
        winners: np.ndarray,
        losers: np.ndarray,
        lengthscale: np.ndarray,
        outputscale: float,
        rng: np.random.Generator,
        tie: np.ndarray | None = None,
    ) -> bool:
        """Target the posterior of duels ``(winners[k], losers[k])`` over points ``X`` ``(n, d)``
        under the kernel ``(lengthscale (d,), outputscale)``; warm-starts the state. ``tie``
        ``(m,)`` bool marks "can't tell" rows (then first/second; needs ``tie_threshold > 0``).

        Returns True if the previous duels are a prefix of the new ones (the state was extended
        and kept), False if the chain was started afresh (sequential draw from no duel).
        """
        X = np.asarray(X, dtype=np.float64)
        winners = np.asarray(winners, dtype=np.int64)
        losers = np.asarray(losers, dtype=np.int64)
        ls = np.asarray(lengthscale, dtype=np.float64).reshape(-1)
        s = float(outputscale)
        if tie is not None:
            tie = np.asarray(tie, dtype=bool).reshape(-1)
            if tie.shape != winners.shape:
                raise ValueError("tie must have one entry per duel")
            if tie.any() and self.tie_threshold <= 0:
                raise ValueError("ties need tie_threshold > 0")
            if not tie.any():
                tie = None
        old_tie = np.zeros(self.num_duels, dtype=bool) if self.tie is None else self.tie
        new_tie = np.zeros(winners.shape[0], dtype=bool) if tie is None else tie
        n0, m0 = self.X.shape[0], self.num_duels
        same_prefix = (
            self.X.shape[1:] == X.shape[1:]
            and X.shape[0] >= n0
            and winners.shape[0] >= m0
            and np.array_equal(X[:n0], self.X)
            and np.array_equal(winners[:m0], self.winners)
            and np.array_equal(losers[:m0], self.losers)
            and np.array_equal(new_tie[:m0], old_tie)
        )
        same_kernel = same_prefix and np.array_equal(ls, self.lengthscale) and s == self.outputscale
        # --- the kernel matrix: extend by the new rows or recompute
        if same_kernel and n0 > 0:
            new = se_kernel_np(X[n0:], X, ls, s)
            K = np.empty((X.shape[0], X.shape[0]))
            K[:n0, :n0] = self.K
            K[n0:, :] = new
            K[:n0, n0:] = new[:, :n0].T
        else:
            K = se_kernel_np(X, X, ls, s)
        # --- the Cholesky factor of M = H K H^T + 2 sigma^2 I
        if same_kernel and m0 > 0 and winners.shape[0] == m0:
            chol = self.chol_M
        elif same_kernel and m0 > 0:
            KHt_new = K[:, winners[m0:]] - K[:, losers[m0:]]
            chol = self._extend_cholesky(KHt_new, winners, losers, m0)
        else:
            M = self._duel_covariance(K, winners, losers)
            chol = np.linalg.cholesky(M) if M.size else np.empty((0, 0))
            self.full_factorizations += 1
        # --- the state
        eps = self.tie_threshold
        if same_prefix:
            g = sequential_extension(self.g, chol, m0, rng, eps, tie)
        else:
            g = sequential_extension(np.empty((self.num_chains, 0)), chol, 0, rng, eps, tie)
        self.tie = tie
        self.X, self.winners, self.losers = X.copy(), winners.copy(), losers.copy()
        self.lengthscale, self.outputscale = ls.copy(), s
        self.K, self.chol_M, self.g = K, chol, g
        return bool(same_prefix)

    def _duel_covariance(
        self, K: np.ndarray, winners: np.ndarray, losers: np.ndarray
    ) -> np.ndarray:
        KHt = K[:, winners] - K[:, losers]
        M = KHt[winners] - KHt[losers]
        M[np.diag_indices_from(M)] += self.noise_var
        return M

    def _extend_cholesky(
        self, KHt_new: np.ndarray, winners: np.ndarray, losers: np.ndarray, m0: int
    ) -> np.ndarray:
        """The factor of the grown ``M`` from the old one: new rows
        ``[l^T, delta]`` with ``l = L^{-1} c``, ``delta = sqrt(d - l^T l)``."""
        m = winners.shape[0]
        cross = KHt_new[winners[:m0]] - KHt_new[losers[:m0]]  # (m0, m - m0): H_old K H_new^T
        corner = KHt_new[winners[m0:]] - KHt_new[losers[m0:]]
        corner[np.diag_indices_from(corner)] += self.noise_var
        L = np.zeros((m, m))
        L[:m0, :m0] = self.chol_M
        low = scipy.linalg.solve_triangular(self.chol_M, cross, lower=True, check_finite=False)
        L[m0:, :m0] = low.T
        L[m0:, m0:] = np.linalg.cholesky(corner - low.T @ low)
        self.extended_rows += m - m0
        return L

    # ------------------------------------------------------------------ sampling
    def run(self, steps: int, rng: np.random.Generator) -> np.ndarray:
        """Advance every chain by ``steps`` LinESS steps; returns the state ``(C, m)``."""
        if self.num_duels == 0:
            return self.g
        g = self.g
        C, m = g.shape
        done = 0
        while done < steps:
            # draw a block of directions at once (one matrix product instead of many
            # matrix-vector products)
            b = min(_BLOCK_STEPS, steps - done)
            nus = rng.standard_normal((b * C, m)) @ self.chol_M.T
            us = rng.random((b, C))
            for i in range(b):
                g = lin_ess_step(
                    g,
                    self.chol_M,
                    rng,
                    nus[i * C : (i + 1) * C],
                    us[i],
                    self.tie_threshold,
                    self.tie,
                )
            done += b
        self.g = g
        return g

    def _solve_M(self, rhs: np.ndarray) -> np.ndarray:
        return scipy.linalg.cho_solve((self.chol_M, True), rhs, check_finite=False)

    def conditioned_gp(self, chain: int = 0) -> ConditionedGP:
        """The GP of ``f`` given the current ``g`` of chain ``chain`` (module docstring)."""
        n = self.X.shape[0]
        H = duel_matrix(self.winners, self.losers, n)
        alpha = H.T @ self._solve_M(self.g[chain])
        W = scipy.linalg.solve_triangular(self.chol_M, H, lower=True, check_finite=False)
        return ConditionedGP(self.X, self.lengthscale, self.outputscale, alpha, W.T @ W)

    def latent_mean(self) -> np.ndarray:
        """``E[f | g]`` at the points for every chain, ``(C, n)``."""
        KHt = self.K[:, self.winners] - self.K[:, self.losers]
        return self._solve_M(self.g.T).T @ KHt.T

    def sample_latent(self, rng: np.random.Generator, jitter: float = 1e-10) -> np.ndarray:
        """A draw of ``f`` at the points given the current ``g`` of every chain, ``(C, n)``,
        by pathwise conditioning (module docstring); ``jitter * s`` is added to the diagonal
        of ``K`` for the prior draw only (near-duplicate points), grown x100 up to ``1e-4 s``
        if the factorisation fails."""
        n = self.X.shape[0]
        C = self.num_chains
        while True:
            try:
                Lk = np.linalg.cholesky(self.K + jitter * self.outputscale * np.eye(n))
                break
            except np.linalg.LinAlgError:
                if jitter >= 1e-4:
                    raise
                jitter *= 100.0
        f0 = rng.standard_normal((C, n)) @ Lk.T
        eps0 = math.sqrt(self.noise_var) * rng.standard_normal((C, self.num_duels))
        resid = self.g - (f0[:, self.winners] - f0[:, self.losers]) - eps0
        KHt = self.K[:, self.winners] - self.K[:, self.losers]
        return f0 + self._solve_M(resid.T).T @ KHt.T
