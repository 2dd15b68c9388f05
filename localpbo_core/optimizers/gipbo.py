"""GIPBO and GIPBOr: gradient-informed local preferential BO (paper Sec. 5.1, App. C.2-C.3,
Alg. GIPBO and its hyperparameter table).

Phase ``t`` at center ``x_t``: ``M = d`` local queries, each chosen by the preferential GI
acquisition (paper eq. (16) "GIPBO acquisition") or at random in the same search region
(GIPBOr), and dueled against the local incumbent ``x*_{t,i-1}`` (which starts at ``x_t`` and
is replaced by a query that wins). GIPBO refits the pairwise GP (hyperparameters learned,
warm-started) before every query; both refit after the ``M`` duels and step

    ``g = mu_grad(x_t)``, ``p = g / sqrt(g^T Lambda g)``, ``x_{t+1} = Pi(x_t + eta p)``

(App. C.2, "Gradient-step normalization"), with the step rescaled to length ``min_step`` if
shorter. Budget accounting and the center's evaluation: :mod:`.local_phase`.

Decisions not fixed by the paper:

* The "SE lengthscale matrix L" of the Mahalanobis norm is read as the kernel's metric
  ``Lambda = diag(1 / l^2)`` (``k = s exp(-0.5 (x - x')^T Lambda (x - x'))``), so the step has
  unit length in the kernel metric and Euclidean length ``eta * |g| / |g|_Lambda``, between
  ``eta * min(l)`` and ``eta * max(l)`` (as GIBO's lengthscale-scaled normalised gradient). With
  ``diag(l^2)`` the step would be at least ``eta / 0.5 = 1`` for every lengthscale in
  ``[0.05, 0.5]``, leaving the local region at every step.
* The virtual duel of the acquisition is against the local incumbent (the duel that will
  actually be run); ``virtual_opponent="center"`` uses ``x_t`` as written in eq.
  GI_PBO_acf_detailed. Both coincide for the first query of a phase.
* Virtual preference likelihood threshold 0.1: see :mod:`.gi_acquisition`.
* A zero (or non-finite) posterior mean gradient gives no step (the phase repeats at x_t).
* If every acquisition candidate coincides with data (possible only in a corner), the query
  is drawn as in GIPBOr.

Beyond the paper (off by default; the paper's settings are the defaults):

* ``accept_step="duel"``: the step's point ``x' = Pi(x_t + eta p)`` is evaluated and dueled
  against the local incumbent ``x*`` in an ask of its own; it becomes ``x_{t+1}`` only if it
  wins, else ``x_{t+1} = x*`` (the step is rejected; the phase's winner, if any, is kept).
  Same evaluations as the paper's (``x'`` is evaluated either way), one more comparison per
  phase (:mod:`.local_phase`, "duel-gated steps"). Under 10 % noise a step the model
  mispredicts then costs one duel instead of a phase spent around a worse center.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Unpack

import numpy as np
import torch

from localpbo_core.optimizers.base import Candidate, DuelAnswer, Outcome
from localpbo_core.optimizers.gi_acquisition import (
    DEFAULT_BOUNDS,
    DEFAULT_RADII,
    gi_pbo_acquisition,
    hypersphere_candidates,
    random_local_query,
)
from localpbo_core.optimizers.local_phase import LocalPhaseOptimizer, LocalPhaseOptions
from localpbo_core.optimizers.preference_optimizer import step_generator
from localpbo_core.validation import SettingError, check_choice, check_float, check_int

VIRTUAL_OPPONENTS = ("incumbent", "center")
ACCEPT_STEPS = ("always", "duel")
#: Accepted spellings of ``virtual_opponent`` values (a user-facing option) -> the canonical one.
_VIRTUAL_OPPONENT_ALIASES = {"centre": "center"}


def normalized_gradient_step(
    gradient: np.ndarray, lengthscale: np.ndarray, step_size: float, min_step: float
) -> np.ndarray:
    """``eta g / sqrt(g^T Lambda g)``, ``Lambda = diag(1/l^2)`` (App. C.2), rescaled to
    Euclidean length ``min_step`` if shorter. Zero for a zero or non-finite gradient."""
    g = np.asarray(gradient, dtype=np.float64)
    norm = float(np.sqrt(np.sum(g * g / np.asarray(lengthscale, dtype=np.float64) ** 2)))
    if not np.isfinite(norm) or norm == 0.0:
        return np.zeros_like(g)
    step = step_size * g / norm
    length = float(np.linalg.norm(step))
    if length < min_step:
        step = step * (min_step / length)
    return step


class GIPBOrOptions(LocalPhaseOptions, total=False):
    """The options of :class:`GIPBOr`: GIPBO's (with their defaults) but those of the
    acquisition."""

    step_size: float
    min_step: float
    num_local_queries: int | None
    search_bounds: tuple[float, float]
    accept_step: str


class GIPBO(LocalPhaseOptimizer):
    """GIPBO (App. C.2, Alg. GIPBO) behind the ask/tell contract.

    Args:
        dim, seed, budget, initial_design, warm_start: see ``PreferenceOptimizer``.
        step_size: eta (table: 0.5).
        min_step: minimum Euclidean step length (table: 0.05).
        num_local_queries: M (table: d; None = d).
        search_bounds: ``(delta_min, delta_max)`` of the local search region (table:
            (0.05, 0.2)); the d <= 2 circles span it.
        radii: hypersphere radii for d > 2 (table: 0.05, 0.1, 0.15, 0.2).
        resolution: candidates per dimension for d > 2 (table: 50).
        max_candidates: cap on the candidate set for d > 2 (App. C.2: 512).
        likelihood_threshold: virtual preference likelihood threshold (table: 0.1).
        virtual_opponent: ``"incumbent"`` (default) or ``"center"`` (see the module docstring;
            the spelling ``"centre"`` is accepted too).
        hyperparameters: fixed GP hyperparameters (App. D.4 within-model runs; see
            :mod:`~localpbo_core.optimizers.surrogate_refit`). Default None: learned.
        accept_step: ``"always"`` (default, the paper's) or ``"duel"``: the step's point
            becomes the next center only if it wins a duel against the local incumbent, else
            the next phase starts at the local incumbent (beyond the paper; module docstring).
    """

    name = "gipbo"
    _random_queries = False

    def __init__(
        self,
        dim: int,
        seed: int,
        budget: int,
        step_size: float = 0.5,
        min_step: float = 0.05,
        num_local_queries: int | None = None,
        search_bounds: tuple[float, float] = DEFAULT_BOUNDS,
        radii: Sequence[float] = DEFAULT_RADII,
        resolution: int = 50,
        max_candidates: int = 512,
        likelihood_threshold: float = 0.1,
        virtual_opponent: str = "incumbent",
        accept_step: str = "always",
        **local: Unpack[LocalPhaseOptions],
    ) -> None:
        super().__init__(dim, seed, budget, **local)
        self.step_size = check_float("step_size", step_size, minimum=0.0, minimum_open=True)
        self.min_step = check_float("min_step", min_step, minimum=0.0)
        self.num_local_queries = (
            self.dim
            if num_local_queries is None
            else check_int("num_local_queries", num_local_queries)
        )
        try:
            lo, hi = (float(b) for b in search_bounds)
        except (TypeError, ValueError) as exc:
            raise SettingError(
                "search_bounds", f"expected two numbers, got {search_bounds!r}"
            ) from exc
        if not (np.isfinite(lo) and np.isfinite(hi) and 0.0 < lo <= hi):
            raise SettingError(
                "search_bounds", f"need 0 < delta_min <= delta_max, got {search_bounds}"
            )
        self.search_bounds = (lo, hi)
        try:
            self.radii = tuple(float(r) for r in radii)
        except (TypeError, ValueError) as exc:
            raise SettingError("radii", f"expected a sequence of numbers, got {radii!r}") from exc
        if not self.radii or any(not np.isfinite(r) or r <= 0 for r in self.radii):
            raise SettingError(
                "radii", f"need a non-empty sequence of positive numbers, got {radii}"
            )
        self.resolution = check_int("resolution", resolution)
        self.max_candidates = check_int("max_candidates", max_candidates)
        self.likelihood_threshold = check_float(
            "likelihood_threshold",
            likelihood_threshold,
            minimum=0.0,
            maximum=0.5,
            maximum_open=True,
        )
        self.virtual_opponent = check_choice(
            "virtual_opponent",
            _VIRTUAL_OPPONENT_ALIASES.get(virtual_opponent, virtual_opponent),
            VIRTUAL_OPPONENTS,
        )
        self.accept_step = check_choice("accept_step", accept_step, ACCEPT_STEPS)
        self._queries_done = 0
        #: GI-PBO values of the last candidate set (for inspection and tests).
        self.last_acquisition: torch.Tensor | None = None

    def _start_phase(self) -> None:
        self._queries_done = 0

    # ------------------------------------------------------------------ queries
    def _local_thetas(self, remaining: int) -> list[np.ndarray]:
        assert self._center_theta is not None
        rng = step_generator(self.seed, self._step)
        if self._random_queries:
            return [random_local_query(self._center_theta, rng, self.search_bounds)]
        surrogate = self._fit()
        cands = hypersphere_candidates(
            self._center_theta,
            rng,
            radii=self.radii,
            resolution=self.resolution,
            max_candidates=self.max_candidates,
            search_bounds=self.search_bounds,
        )
        opp = (
            self._local_incumbent_theta()
            if self.virtual_opponent == "incumbent"
            else self._center_theta
        )
        acq = gi_pbo_acquisition(
            surrogate,
            torch.tensor(self._center_theta, dtype=torch.float64),
            torch.tensor(cands, dtype=torch.float64),
            torch.tensor(opp, dtype=torch.float64),
            likelihood_threshold=self.likelihood_threshold,
        )
        self.last_acquisition = acq
        if not torch.isfinite(acq).any():
            return [random_local_query(self._center_theta, rng, self.search_bounds)]
        return [cands[int(torch.argmax(acq))]]

    def _local_opponent(self) -> int:
        assert self._local_inc_id is not None
        return self._local_inc_id

    # ------------------------------------------------------------------ tell
    def _after_duels(
        self, candidates: tuple[Candidate, ...], outcomes: tuple[DuelAnswer, ...]
    ) -> None:
        query = candidates[-1].id
        # a "can't tell" answer keeps the local incumbent (no win)
        if any(isinstance(o, Outcome) and o.winner == query for o in outcomes):
            self._local_inc_id = query
        assert self._local_inc_id is not None  # the center was registered with this ask
        self._set_incumbent(self._local_inc_id)
        self._queries_done += 1
        if self._queries_done < self.num_local_queries:
            return
        surrogate = self._fit()
        assert self._center_theta is not None
        x = torch.tensor(self._center_theta, dtype=torch.float64)
        g = surrogate.mean_gradient(x).detach().numpy()
        ls = surrogate.lengthscale.detach().numpy()
        step = normalized_gradient_step(g, ls, self.step_size, self.min_step)
        if self.accept_step == "duel":
            self._ask_trial([self._center_theta + step])
        else:
            self._move_center(self._center_theta + step)


class GIPBOr(GIPBO):
    """GIPBOr (App. C.3): GIPBO with random local queries (uniform direction, radius uniform
    in ``search_bounds``, projected onto ``[0,1]^d``); one GP fit per gradient step. Options as
    GIPBO's, without those of the acquisition."""

    name = "gipbor"
    _random_queries = True

    def __init__(self, dim: int, seed: int, budget: int, **options: Unpack[GIPBOrOptions]) -> None:
        super().__init__(dim, seed, budget, **options)
