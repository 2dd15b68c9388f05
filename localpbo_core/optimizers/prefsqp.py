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

The chosen point is the next iterate (evaluated with the next ask, see
:mod:`.local_phase`). Decisions: eigenvalue modification ``lambda -> -max(|lambda|, floor)``
with ``floor = eigenvalue_floor * max(max|lambda|, 1e-12)`` (Nocedal & Wright's
absolute-value modification, sign-flipped for maximisation: positive curvature directions
are kept as ascent directions, never dropped); the incumbent after a phase is the first
(lowest id) local sample that beat ``x_t``, else ``x_t``.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
import torch

from localpbo_core.optimizers.acquisition import eubo_from_moments
from localpbo_core.optimizers.base import Candidate, Outcome
from localpbo_core.optimizers.local_phase import LocalPhaseOptimizer
from localpbo_core.optimizers.preference_optimizer import step_generator
from localpbo_core.surrogate import Surrogate
from localpbo_core.validation import check_choice, check_float, check_int

LINE_SEARCHES = ("thompson", "full", "eubo")
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


def line_search_points(x: np.ndarray, p: np.ndarray, resolution: int = 100) -> np.ndarray:
    """``Pi([0,1]^d)(x + eta_r p)`` for ``eta_r = 0, 1/(R-1), ..., 1`` (Alg. PrefSQP)."""
    eta = np.linspace(0.0, 1.0, resolution)
    return np.clip(x[None, :] + eta[:, None] * p[None, :], 0.0, 1.0)


def ball_samples(center: np.ndarray, radius: float, n: int, rng: np.random.Generator) -> np.ndarray:
    """``n`` points uniform in ``B_radius(center) cap [0,1]^d`` by rejection (uniform in the
    ball: Gaussian direction, radius ``radius * U^{1/d}``). After 1000 rounds without enough
    accepted points the remaining ones are projected onto the cube."""
    d = center.shape[0]
    out: list[np.ndarray] = []

    def draw(k: int) -> np.ndarray:
        z = rng.standard_normal((k, d))
        z /= np.maximum(np.linalg.norm(z, axis=1, keepdims=True), 1e-300)
        r = radius * rng.random((k, 1)) ** (1.0 / d)
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
        line_search_resolution: grid size R (table: 100).
        num_features: random features of the Thompson sample path.
        eigenvalue_floor: relative floor of the eigenvalue modification.
        hyperparameters: fixed GP hyperparameters, e.g. ``{"lengthscale": 0.1,
            "outputscale": 1.0}`` (within-model runs, App. D.4); see
            :mod:`~localpbo_core.optimizers.surrogate_refit`. Default None: learned.
    """

    name = "prefsqp"

    def __init__(
        self,
        dim: int,
        seed: int,
        budget: int,
        initial_design: int = 2,
        warm_start: Sequence[float] | np.ndarray | None = None,
        epsilon: float = 0.05,
        num_local_samples: int | None = None,
        line_search: str = "thompson",
        line_search_resolution: int = 100,
        num_features: int = 1024,
        eigenvalue_floor: float = 1e-6,
        hyperparameters: Mapping[str, object] | None = None,
    ) -> None:
        super().__init__(
            dim,
            seed,
            budget,
            initial_design=initial_design,
            warm_start=warm_start,
            hyperparameters=hyperparameters,
        )
        self.epsilon = check_float("epsilon", epsilon, minimum=0.0, minimum_open=True)
        self.num_local_samples = (
            self.dim
            if num_local_samples is None
            else check_int("num_local_samples", num_local_samples)
        )
        self.line_search = check_choice("line_search", line_search, LINE_SEARCHES)
        self.line_search_resolution = check_int(
            "line_search_resolution", line_search_resolution, minimum=2
        )
        self.num_features = check_int("num_features", num_features)
        self.eigenvalue_floor = check_float(
            "eigenvalue_floor", eigenvalue_floor, minimum=0.0, maximum=1.0, minimum_open=True
        )
        #: Newton directions of every completed phase (for inspection and tests).
        self.directions: list[np.ndarray] = []

    # ------------------------------------------------------------------ queries
    def _local_thetas(self, remaining: int) -> list[np.ndarray]:
        assert self._center_theta is not None
        rng = step_generator(self.seed, self._step)
        n = min(self.num_local_samples, remaining)
        return list(ball_samples(self._center_theta, self.epsilon, n, rng))

    def _local_opponent(self) -> int:
        assert self._center_id is not None
        return self._center_id

    # ------------------------------------------------------------------ tell
    def _after_duels(
        self, candidates: tuple[Candidate, ...], outcomes: tuple[Outcome, ...]
    ) -> None:
        center = self._center_id
        winners = sorted(o.winner for o in outcomes if o.loser == center)
        assert center is not None
        self._set_incumbent(winners[0] if winners else center)
        surrogate = self._fit()
        assert self._center_theta is not None
        x = torch.tensor(self._center_theta, dtype=torch.float64)
        g = surrogate.mean_gradient(x).detach().numpy()
        H = surrogate.mean_hessian(x).detach().numpy()
        if not (np.all(np.isfinite(g)) and np.all(np.isfinite(H))) or not np.any(g):
            p = np.zeros(self.dim)
        else:
            p = newton_direction(g, H, self.eigenvalue_floor)
        self.directions.append(p)
        rng = step_generator(self.seed, self._step, 1)
        self._move_center(self._line_search(surrogate, self._center_theta, p, rng))

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
