"""PrefSQP: preference-based sequential quadratic programming (paper Sec. 5.2, App. C.4,
Alg. PrefSQP and its hyperparameter table; ablations of App. D.7).

Phase ``t`` at the iterate ``x_t``: ``M = d`` points uniform in ``B_eps(x_t) cap [0,1]^d``
(eps = 0.05), all dueled against ``x_t`` in one ask; refit (hyperparameters learned,
warm-started); ``g = mu_grad(x_t)``, ``H = mu_hess(x_t)``; eigenvalue modification to a
negative-definite ``H~``; Newton direction ``p = -H~^{-1} g`` (eq. (19) "Newton direction"); line
search over ``Pi(x_t + eta p)``, ``eta`` on a grid of 100 points in ``[0, 1]``:

* ``"thompson"`` (default): argmax of one posterior sample path on the grid;
* ``"full"``: ``eta = 1`` (App. D.7 ablation);
* ``"eubo"``: argmax of EUBO of each grid point against ``x_t`` under the joint Laplace
  posterior (App. D.7 ablation).

Subproblem (``subproblem`` option):

* ``"newton"`` (default): the Newton subproblem of Sec. 5.2 (eqs. (18)-(19)), solved in
  closed form as above.
* ``"ev"`` (App. D.7 ablation): the analogue of the uncertainty-aware subproblem of BayeSQP
  (Paul Brunzema, Sebastian Trimpe, *BayeSQP: Bayesian Optimization through Sequential
  Quadratic Programming*, NeurIPS 2025; arXiv:2602.03232). BayeSQP replaces the SQP model
  ``f(x) + grad f(x)^T p`` by a quantile of its Gaussian posterior plus the quadratic term,
  a second-order cone program over the box. With preferences only differences of the
  utility are observable, so we take the predicted improvement ``f(x + p) - f(x) ~=
  grad f(x)^T p + 1/2 p^T H~ p``; under the pairwise-GP posterior ``grad f(x) ~ N(g,
  Sigma_11(x))`` (eq. (15), :meth:`Surrogate.gradient_covariance`), so the improvement has
  mean ``g^T p + 1/2 p^T H~ p`` and standard deviation ``sqrt(p^T Sigma_11 p)`` (the Hessian
  enters at its eigenvalue-modified posterior mean). ``p`` maximises its lower
  ``ev_delta``-quantile over the box::

      max_p  g^T p + 1/2 p^T H~ p - kappa sqrt(p^T Sigma_11 p)
      s.t.   0 <= x + p <= 1,           kappa = Phi^{-1}(1 - ev_delta).

  ``H~`` is negative definite and the square-root term convex, so the objective is concave
  and the maximiser unique. ``ev_delta = 0.5`` (``kappa = 0``) is the pure expected value of
  the quadratic model (the expectation of a model linear in ``g`` is the model at the
  posterior mean), i.e. the box-constrained Newton subproblem; the default 0.2 is BayeSQP's
  default ``delta_f``. A large gradient uncertainty shortens the step (and gives ``p = 0``
  when ``kappa ||Sigma_11^{1/2} u|| >= g^T u`` in every feasible direction ``u``: no step
  with a confident predicted improvement). Solved by L-BFGS-B on the box from the clipped
  Newton step and from a short clipped gradient step (see :func:`ev_subproblem`).

The chosen point is the next iterate (evaluated with the next ask, see
:mod:`.local_phase`). Decisions: eigenvalue modification ``lambda -> -max(|lambda|, floor)``
with ``floor = eigenvalue_floor * max(max|lambda|, 1e-12)`` (Nocedal & Wright's
absolute-value modification, sign-flipped for maximisation: positive curvature directions
are kept as ascent directions, never dropped); the incumbent after a phase is the first
(lowest id) local sample that beat ``x_t``, else ``x_t``.

Beyond the paper (options, off by default; the defaults are the paper's settings and give
the paper's candidates). Under 10 % noise the ``eps = 0.05`` ball holds true differences of a
few hundredths of the noise's standard deviation, so about half its duels are decided by the
noise and the Newton step, not normalised, often leaves the box. Each option addresses one
cause:

* ``sampling_radius="lengthscale"``: the ``M`` samples are uniform in the ellipsoid
  ``{x_t + rho l * u : |u| <= 1} cap [0,1]^d`` (``l`` the ARD lengthscales of the last fit,
  elementwise product, ``rho = radius_scale``, default 1), by the same rejection as the
  ball. Every sample then lies within ``rho`` in the kernel metric ``|x - x_t|_Lambda``,
  ``Lambda = diag(1 / l^2)``: the prior correlation with ``x_t`` is at least
  ``exp(-rho^2 / 2)`` whatever the lengthscales, and the differences dueled are of the order
  of the function's local variation rather than of a fixed 0.05.
* ``step_normalization="kernel"``: the subproblem's solution is rescaled to length
  ``eta = step_size`` in the kernel metric, ``p <- eta p / sqrt(p^T Lambda p)`` (GIPBO's
  normalisation, App. C.2; default ``eta = 0.5``), before the line search. The Newton
  direction is kept; its length, which the noisy Hessian sets, is not.
* ``line_search="duel"``: instead of choosing ``eta`` on the model, the ``K = duel_points``
  points ``Pi(x_t + (k/K) p)``, ``k = 1..K``, are evaluated and each dueled against the local
  incumbent (as the line search of BayeSQP's code evaluates its points; with preferences the
  evaluations are duels). The winner of highest posterior mean becomes ``x_{t+1}``; with no
  winner the step is rejected and ``x_{t+1}`` is the local incumbent. K evaluations and K
  comparisons per phase.
* ``accept_step="duel"``: the line search's point ``x'`` is evaluated and dueled against the
  local incumbent in an ask of its own; ``x_{t+1} = x'`` if it wins, else the local
  incumbent. Same evaluations as the paper's, one more comparison per phase.

The gating mechanics (trial asks, the accounting) are :mod:`.local_phase`'s "duel-gated
steps"; the ``"duel"`` line search is gated by construction, ``accept_step`` adds nothing
to it.
"""

from __future__ import annotations

from typing import Unpack

import numpy as np
import scipy.optimize
import scipy.stats
import torch

from localpbo_core.optimizers.acquisition import eubo_from_moments
from localpbo_core.optimizers.base import Candidate, DuelAnswer, Outcome
from localpbo_core.optimizers.local_phase import LocalPhaseOptimizer, LocalPhaseOptions
from localpbo_core.optimizers.preference_optimizer import step_generator
from localpbo_core.surrogate import Surrogate
from localpbo_core.validation import check_choice, check_float, check_int

LINE_SEARCHES = ("thompson", "full", "eubo", "duel")
SUBPROBLEMS = ("newton", "ev")
SAMPLING_RADII = ("fixed", "lengthscale")
STEP_NORMALIZATIONS = ("none", "kernel")
ACCEPT_STEPS = ("always", "duel")
_MAX_REJECTION_ROUNDS = 1000


def negative_definite_modification(H: np.ndarray, floor: float = 1e-6) -> np.ndarray:
    """Symmetrise ``H`` and replace every eigenvalue ``lambda`` by ``-max(|lambda|, f)``,
    ``f = floor * max(max|lambda|, 1e-12)`` (App. C.4, "eigenvalue modification")."""
    Hs = 0.5 * (np.asarray(H, dtype=np.float64) + np.asarray(H, dtype=np.float64).T)
    lam, V = np.linalg.eigh(Hs)
    f = floor * max(float(np.max(np.abs(lam))), 1e-12)
    lam_mod = -np.maximum(np.abs(lam), f)
    return (V * lam_mod) @ V.T


def newton_direction(g: np.ndarray, H: np.ndarray, floor: float = 1e-6) -> np.ndarray:
    """``p = -H~^{-1} g`` (eq. (19) "Newton direction") with ``H~`` from
    :func:`negative_definite_modification`; ``g^T p > 0`` whenever ``g != 0``."""
    Ht = negative_definite_modification(H, floor)
    return -np.linalg.solve(Ht, np.asarray(g, dtype=np.float64))


def ev_objective(
    p: np.ndarray, g: np.ndarray, Ht: np.ndarray, sigma: np.ndarray, kappa: float
) -> float:
    """``g^T p + 1/2 p^T H~ p - kappa sqrt(p^T Sigma p)`` (module docstring, ``"ev"``)."""
    p = np.asarray(p, dtype=np.float64)
    return float(g @ p + 0.5 * p @ Ht @ p - kappa * np.sqrt(max(float(p @ sigma @ p), 0.0)))


def ev_subproblem(
    x: np.ndarray,
    g: np.ndarray,
    H: np.ndarray,
    sigma: np.ndarray,
    delta: float,
    floor: float = 1e-6,
) -> np.ndarray:
    """Solve the uncertainty-aware subproblem (module docstring, ``"ev"``).

    ``H`` is modified to ``H~`` (:func:`negative_definite_modification`); ``Sigma`` is
    symmetrised and its negative eigenvalues (round-off) set to 0. The square root is
    smoothed to ``sqrt(p^T Sigma p + t^2) - t`` with ``t = 1e-9 * (1 + ||Sigma||)`` for
    L-BFGS-B (an error of at most ``kappa t`` in the objective); starts: the Newton step
    and the gradient step ``g / ||H~||``, both clipped to the box. The best of the two runs
    and ``p = 0`` (judged on the exact objective) is returned, so the step never has a worse
    model value than staying.
    """
    x = np.asarray(x, dtype=np.float64)
    g = np.asarray(g, dtype=np.float64)
    Ht = negative_definite_modification(H, floor)
    S = 0.5 * (np.asarray(sigma, dtype=np.float64) + np.asarray(sigma, dtype=np.float64).T)
    lam, V = np.linalg.eigh(S)
    S = (V * np.maximum(lam, 0.0)) @ V.T
    kappa = float(scipy.stats.norm.ppf(1.0 - delta))
    t = 1e-9 * (1.0 + float(np.max(np.abs(lam))))
    lo, hi = -x, 1.0 - x

    def neg(p: np.ndarray) -> tuple[float, np.ndarray]:
        Sp = S @ p
        r = np.sqrt(max(float(p @ Sp), 0.0) + t * t)
        val = g @ p + 0.5 * p @ Ht @ p - kappa * (r - t)
        grad = g + Ht @ p - kappa * Sp / r
        return -float(val), -grad

    starts = [
        np.clip(-np.linalg.solve(Ht, g), lo, hi),
        np.clip(g / max(float(np.max(np.abs(np.linalg.eigvalsh(Ht)))), 1e-300), lo, hi),
    ]
    best = np.zeros_like(g)
    best_val = 0.0
    for p0 in starts:
        res = scipy.optimize.minimize(
            neg,
            p0,
            jac=True,
            method="L-BFGS-B",
            bounds=scipy.optimize.Bounds(lo, hi),
            options={"maxiter": 2000, "ftol": 1e-15, "gtol": 1e-12},
        )
        p = np.clip(res.x, lo, hi)
        val = ev_objective(p, g, Ht, S, kappa)
        if val > best_val:
            best, best_val = p, val
    return best


def kernel_normalized_step(p: np.ndarray, lengthscale: np.ndarray, step_size: float) -> np.ndarray:
    """``eta p / sqrt(p^T Lambda p)``, ``Lambda = diag(1 / l^2)``: the direction ``p`` scaled to
    length ``eta`` in the kernel metric (as GIPBO's step, App. C.2). Zero for a zero or
    non-finite ``p``."""
    p = np.asarray(p, dtype=np.float64)
    norm = float(np.sqrt(np.sum(p * p / np.asarray(lengthscale, dtype=np.float64) ** 2)))
    if not np.isfinite(norm) or norm == 0.0:
        return np.zeros_like(p)
    return step_size * p / norm


def duel_line_points(x: np.ndarray, p: np.ndarray, count: int) -> np.ndarray:
    """``Pi([0,1]^d)(x + eta_k p)`` for ``eta_k = k / K``, ``k = 1..K`` (the points the
    ``"duel"`` line search evaluates and duels)."""
    eta = np.arange(1, count + 1, dtype=np.float64) / count
    return np.clip(x[None, :] + eta[:, None] * p[None, :], 0.0, 1.0)


def line_search_points(x: np.ndarray, p: np.ndarray, resolution: int = 100) -> np.ndarray:
    """``Pi([0,1]^d)(x + eta_r p)`` for ``eta_r = 0, 1/(R-1), ..., 1`` (Alg. PrefSQP)."""
    eta = np.linspace(0.0, 1.0, resolution)
    return np.clip(x[None, :] + eta[:, None] * p[None, :], 0.0, 1.0)


def ball_samples(
    center: np.ndarray,
    radius: float,
    n: int,
    rng: np.random.Generator,
    axes: np.ndarray | None = None,
) -> np.ndarray:
    """``n`` points uniform in ``B_radius(center) cap [0,1]^d`` by rejection (uniform in the
    ball: Gaussian direction, radius ``radius * U^{1/d}``). After 1000 rounds without enough
    accepted points the remaining ones are projected onto the cube. With ``axes`` (shape
    ``(d,)``, positive) the ball is stretched to the ellipsoid ``{center + radius a * u : |u|
    <= 1}`` (``a * u`` elementwise), still uniform."""
    d = center.shape[0]
    out: list[np.ndarray] = []

    def draw(k: int) -> np.ndarray:
        z = rng.standard_normal((k, d))
        z /= np.maximum(np.linalg.norm(z, axis=1, keepdims=True), 1e-300)
        r = radius * rng.random((k, 1)) ** (1.0 / d)
        if axes is not None:
            return center + r * z * axes[None, :]
        return center + r * z

    for _ in range(_MAX_REJECTION_ROUNDS):
        pts = draw(n)
        inside = pts[np.all((pts >= 0.0) & (pts <= 1.0), axis=1)]
        out.extend(inside[: n - len(out)])
        if len(out) >= n:
            return np.array(out[:n])
    extra = np.clip(draw(n - len(out)), 0.0, 1.0)
    return np.concatenate([np.array(out).reshape(-1, d), extra], axis=0)


class PrefSQP(LocalPhaseOptimizer):
    """PrefSQP (App. C.4, Alg. PrefSQP) behind the ask/tell contract.

    Args:
        dim, seed, budget, initial_design, warm_start: see ``PreferenceOptimizer``.
        epsilon: local sampling radius (table: 0.05).
        num_local_samples: M (table: d; None = d).
        line_search: ``"thompson"`` (default), ``"full"`` or ``"eubo"``.
        subproblem: ``"newton"`` (default) or ``"ev"`` (BayeSQP's uncertainty-aware
            subproblem on the pairwise-GP posterior; module docstring).
        ev_delta: quantile level ``delta`` in ``(0, 0.5]`` of ``"ev"`` (default 0.2).
        line_search_resolution: grid size R (table: 100).
        num_features: random features of the Thompson sample path.
        eigenvalue_floor: relative floor of the eigenvalue modification.
        hyperparameters: fixed GP hyperparameters (App. D.4 within-model runs; see
            :mod:`~localpbo_core.optimizers.surrogate_refit`). Default None: learned.
        sampling_radius: ``"fixed"`` (default: the ball of radius ``epsilon``) or
            ``"lengthscale"`` (the ellipsoid of semi-axes ``radius_scale * l``; beyond the
            paper, module docstring).
        radius_scale: ``rho`` of the ``"lengthscale"`` radius (default 1.0).
        step_normalization: ``"none"`` (default: the Newton step as solved) or ``"kernel"``
            (length ``step_size`` in the kernel metric; beyond the paper).
        step_size: ``eta`` of the ``"kernel"`` normalization (default 0.5, GIPBO's).
        duel_points: K, points of the ``"duel"`` line search (default 3).
        accept_step: ``"always"`` (default) or ``"duel"`` (the line search's point becomes
            the center only if it wins a duel; beyond the paper).
    """

    name = "prefsqp"

    def __init__(
        self,
        dim: int,
        seed: int,
        budget: int,
        epsilon: float = 0.05,
        num_local_samples: int | None = None,
        line_search: str = "thompson",
        subproblem: str = "newton",
        ev_delta: float = 0.2,
        line_search_resolution: int = 100,
        num_features: int = 1024,
        eigenvalue_floor: float = 1e-6,
        sampling_radius: str = "fixed",
        radius_scale: float = 1.0,
        step_normalization: str = "none",
        step_size: float = 0.5,
        duel_points: int = 3,
        accept_step: str = "always",
        **local: Unpack[LocalPhaseOptions],
    ) -> None:
        super().__init__(dim, seed, budget, **local)
        self.epsilon = check_float("epsilon", epsilon, minimum=0.0, minimum_open=True)
        self.num_local_samples = (
            self.dim
            if num_local_samples is None
            else check_int("num_local_samples", num_local_samples)
        )
        self.line_search = check_choice("line_search", line_search, LINE_SEARCHES)
        self.subproblem = check_choice("subproblem", subproblem, SUBPROBLEMS)
        self.ev_delta = check_float(
            "ev_delta", ev_delta, minimum=0.0, maximum=0.5, minimum_open=True
        )
        self.line_search_resolution = check_int(
            "line_search_resolution", line_search_resolution, minimum=2
        )
        self.num_features = check_int("num_features", num_features)
        self.eigenvalue_floor = check_float(
            "eigenvalue_floor", eigenvalue_floor, minimum=0.0, maximum=1.0, minimum_open=True
        )
        self.sampling_radius = check_choice("sampling_radius", sampling_radius, SAMPLING_RADII)
        self.radius_scale = check_float(
            "radius_scale", radius_scale, minimum=0.0, minimum_open=True
        )
        self.step_normalization = check_choice(
            "step_normalization", step_normalization, STEP_NORMALIZATIONS
        )
        self.step_size = check_float("step_size", step_size, minimum=0.0, minimum_open=True)
        self.duel_points = check_int("duel_points", duel_points)
        self.accept_step = check_choice("accept_step", accept_step, ACCEPT_STEPS)
        #: Step directions (subproblem solutions) of every completed phase (inspection, tests).
        self.directions: list[np.ndarray] = []

    # ------------------------------------------------------------------ queries
    def _local_thetas(self, remaining: int) -> list[np.ndarray]:
        assert self._center_theta is not None
        rng = step_generator(self.seed, self._step)
        n = min(self.num_local_samples, remaining)
        if self.sampling_radius == "lengthscale":
            ls = self._fit().lengthscale.detach().numpy().reshape(-1)
            return list(ball_samples(self._center_theta, self.radius_scale, n, rng, axes=ls))
        return list(ball_samples(self._center_theta, self.epsilon, n, rng))

    def _local_opponent(self) -> int:
        assert self._center_id is not None
        return self._center_id

    # ------------------------------------------------------------------ tell
    def _after_duels(
        self, candidates: tuple[Candidate, ...], outcomes: tuple[DuelAnswer, ...]
    ) -> None:
        center = self._center_id
        # a "can't tell" answer is no win: the center stays the incumbent
        winners = sorted(o.winner for o in outcomes if isinstance(o, Outcome) and o.loser == center)
        assert center is not None
        self._set_incumbent(winners[0] if winners else center)
        surrogate = self._fit()
        assert self._center_theta is not None
        x = torch.tensor(self._center_theta, dtype=torch.float64)
        g = surrogate.mean_gradient(x).detach().numpy()
        H = surrogate.mean_hessian(x).detach().numpy()
        sigma = (
            surrogate.gradient_covariance(x).detach().numpy()
            if self.subproblem == "ev"
            else np.zeros((self.dim, self.dim))
        )
        finite = all(np.all(np.isfinite(a)) for a in (g, H, sigma))
        if not finite or not np.any(g):
            p = np.zeros(self.dim)
        elif self.subproblem == "ev":
            p = ev_subproblem(self._center_theta, g, H, sigma, self.ev_delta, self.eigenvalue_floor)
        else:
            p = newton_direction(g, H, self.eigenvalue_floor)
        if self.step_normalization == "kernel":
            p = kernel_normalized_step(
                p, surrogate.lengthscale.detach().numpy().reshape(-1), self.step_size
            )
        self.directions.append(p)
        if self.line_search == "duel":
            self._ask_trial(list(duel_line_points(self._center_theta, p, self.duel_points)))
            return
        rng = step_generator(self.seed, self._step, 1)
        nxt = self._line_search(surrogate, self._center_theta, p, rng)
        if self.accept_step == "duel":
            self._ask_trial([nxt])
        else:
            self._move_center(nxt)

    def _line_search(
        self, surrogate: Surrogate, x: np.ndarray, p: np.ndarray, rng: np.random.Generator
    ) -> np.ndarray:
        """Select the next iterate on the line (module docstring)."""
        if self.line_search == "full":
            return np.clip(x + p, 0.0, 1.0)
        pts = line_search_points(x, p, self.line_search_resolution)
        pts_t = torch.tensor(pts, dtype=torch.float64)
        with torch.no_grad():
            if self.line_search == "thompson":
                gen = torch.Generator().manual_seed(int(rng.integers(0, 2**62)))
                path = surrogate.sample_paths(1, gen, num_features=self.num_features)
                values = path(pts_t)[:, 0]
            else:
                both = torch.cat([torch.tensor(x, dtype=torch.float64)[None], pts_t])
                mean, cov = surrogate.posterior_mean_cov(both)
                values = eubo_from_moments(mean, cov)
        return pts[int(torch.argmax(values))]
