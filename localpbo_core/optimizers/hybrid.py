"""Hybrid: TuRPBO's global exploration handing over to derivative-informed local steps
(beyond the paper; the combination its conclusion names as the next step).

Two modes share one pairwise GP (refit on every duel, as TuRPBO's, paper Sec. 4) and one
trust-region state (:class:`~localpbo_core.optimizers.trust_region.TrustRegionState`,
App. C.5):

* **global**: a TuRPBO iteration (:class:`~localpbo_core.optimizers.turpbo.TuRPBO`, Alg.
  TurPBO): ``q`` candidates in the lengthscale-weighted box around the center, each dueled
  against the center. Until the first handover the hybrid asks exactly TuRPBO's candidates.
* **local**: one step from the center ``x_c`` as GIPBO's (App. C.2) or PrefSQP's (Sec. 5.2):
  direction ``u = g = grad mu(x_c)`` (``local_direction="gradient"``) or the Newton
  direction ``u = -H~^{-1} g`` (``"newton"``, eq. (19), ``H~`` the negative-definite
  modification of ``hess mu(x_c)``), scaled to length ``eta 2^{-j}`` in the kernel metric,

      ``x' = Pi(x_c + eta 2^{-j} u / sqrt(u^T Lambda u))``,  ``Lambda = diag(1 / l^2)``,

  where ``j`` is the number of losing local steps since the last win (a backtracking line
  search carried out by duels: each halving is one duel). ``x'`` is dueled against the
  center; a win moves the center (and the incumbent, if the center was it) to ``x'``.

**Handover to local** (checked at every global ask, on the fit of that ask, after at least
``cooldown`` global iterations since the last hand-back): the model is confident about the
slope along the step. Under the Laplace posterior ``grad f(x_c) ~ N(g, Sigma_11(x_c))``
(eq. (15), :meth:`Surrogate.gradient_covariance`), the directional derivative along ``u`` has
mean ``g^T u`` and standard deviation ``sqrt(u^T Sigma_11 u)``; the hybrid goes local iff

    ``z = g^T u / sqrt(u^T Sigma_11 u) >= confidence``   (default 1: ascent along ``u`` with
    posterior probability ``Phi(1) = 0.84``; under 10 % noise ``z`` rarely reaches 2 within
    the paper's budget, measured on Hartmann 6).

With ``handover_length > 0`` the hybrid also hands over when the trust region's side ``L``
has shrunk to at most ``handover_length`` (the global search has failed repeatedly in the
box; off by default).

**Hand-back to global**: after ``stall_duels`` consecutive local steps without a win (a
"can't tell" answer is no win), or when the step would not leave the center (a corner), or
when the trust region restarts.

**Probes** (``probes_per_dim > 0``; off by default): a local phase at origin ``x_o`` (the
center at the handover, the new center after a winning step) first asks
``m = ceil(probes_per_dim * d)`` probes, GIPBOr's random local queries around ``x_o`` (App.
C.3: a uniform direction ``u``, a radius ``r``, projected onto the cube). With
``probe_metric="kernel"`` (default) ``r`` is uniform in ``[0.5, 2]`` in the kernel metric,

    ``x = Pi(x_o + r l * u)``   (elementwise; ``l`` the lengthscales of the fit that started
    the phase, so ``sqrt((x - x_o)^T Lambda (x - x_o)) = r`` before the projection),

which is GIPBOr's region ``[0.05, 0.2]`` where ``l = 0.1`` and scales with the model elsewhere;
``"euclidean"`` takes GIPBOr's region ``[0.05, 0.2]`` whatever ``l``. ``probe_scale`` ``s``
multiplies both intervals (``[0.5 s, 2 s]``, ``[0.05 s, 0.2 s]``): nearer probes cost less value
(the cumulative metric), and their duels are closer calls under the noise. Each probe is dueled
against the center, and then the phase steps from ``x_o``, the gradient read at ``x_o``: a fit
that has seen duels around ``x_o`` in every direction (GIPBOr's phase, ``M = d`` with
``probes_per_dim = 1``) rather than only the trust region's candidates. A probe asks no fit;
it is a trust-region iteration as any other (a win moves the center, so the step is dueled
against the phase's best point so far), and neither a win nor a loss counts towards
``stall_duels``. A losing step halves the next, from the same origin, without new probes.

Every iteration, global, probe or local, updates the trust region's counters as a TuRPBO
iteration (success iff the new point beats the center), so local failures shrink the region
the global phase returns to, and local wins count towards its expansion. Restarts and the
challenge duel of a new center against the global incumbent are TuRPBO's. With ``q > 1`` a
local step (and a probe) still asks one candidate.
"""

from __future__ import annotations

from typing import Unpack

import numpy as np
import torch

from localpbo_core.optimizers.base import Ask, Candidate, DuelAnswer
from localpbo_core.optimizers.gi_acquisition import (
    DEFAULT_BOUNDS,
    random_local_query,
    sphere_directions,
)
from localpbo_core.optimizers.prefsqp import kernel_normalized_step, negative_definite_modification
from localpbo_core.optimizers.turpbo import TuRPBO, TuRPBOOptions
from localpbo_core.surrogate.data import DUPLICATE_ATOL
from localpbo_core.surrogate.protocol import Surrogate
from localpbo_core.validation import check_choice, check_float, check_int

LOCAL_DIRECTIONS = ("gradient", "newton")
MODES = ("global", "probe", "local")
PROBE_METRICS = ("kernel", "euclidean")
KERNEL_PROBE_BOUNDS = (0.5, 2.0)
"""Radii of the probes in the kernel metric (module docstring)."""


def slope_confidence(g: np.ndarray, u: np.ndarray, sigma: np.ndarray) -> float:
    """``z = g^T u / sqrt(u^T Sigma u)``: the posterior z-score of the directional derivative
    along ``u`` (module docstring). ``inf`` for a certain positive slope, 0 for ``u = 0``."""
    slope = float(g @ u)
    var = float(u @ (0.5 * (sigma + sigma.T)) @ u)
    if not np.isfinite(slope) or not np.isfinite(var) or slope <= 0.0:
        return 0.0
    if var <= 0.0:
        return float("inf")
    return slope / float(np.sqrt(var))


class Hybrid(TuRPBO):
    """TuRPBO exploration + kernel-metric local steps (module docstring).

    Args:
        dim, seed, budget, initial_design, warm_start: see ``PreferenceOptimizer``.
        batch_size, acquisition, num_raw_samples, num_restarts, num_features,
            num_mc_samples, hyperparameter_refit_every, hyperparameters: TuRPBO's (the
            global mode).
        confidence: handover threshold on ``z`` (default 1.0).
        local_direction: ``"gradient"`` (default) or ``"newton"``.
        step_size: ``eta``, the local step's length in the kernel metric (default 0.5,
            GIPBO's).
        stall_duels: k, consecutive losing local steps before the hand-back (default 3).
        cooldown: global iterations after a hand-back before the next handover check
            (default 4).
        eigenvalue_floor: relative floor of the Newton direction's eigenvalue modification.
        handover_length: also hand over when the trust region's side is at most this
            (default 0: off; module docstring).
        probes_per_dim: probes per local phase over ``d`` (default 0: none; module
            docstring).
        probe_metric: ``"kernel"`` (default) or ``"euclidean"``: where the probes' radii are
            measured (module docstring).
        probe_scale: ``s``, a factor on the probes' radii (default 1; module docstring).
    """

    name = "hybrid"

    def __init__(
        self,
        dim: int,
        seed: int,
        budget: int,
        confidence: float = 1.0,
        local_direction: str = "gradient",
        step_size: float = 0.5,
        stall_duels: int = 3,
        cooldown: int = 4,
        eigenvalue_floor: float = 1e-6,
        handover_length: float = 0.0,
        probes_per_dim: float = 0.0,
        probe_metric: str = "kernel",
        probe_scale: float = 1.0,
        **turpbo: Unpack[TuRPBOOptions],
    ) -> None:
        super().__init__(dim, seed, budget, **turpbo)
        self.confidence = check_float("confidence", confidence, minimum=0.0)
        self.local_direction = check_choice("local_direction", local_direction, LOCAL_DIRECTIONS)
        self.step_size = check_float("step_size", step_size, minimum=0.0, minimum_open=True)
        self.stall_duels = check_int("stall_duels", stall_duels)
        self.cooldown = check_int("cooldown", cooldown, minimum=0)
        self.eigenvalue_floor = check_float(
            "eigenvalue_floor", eigenvalue_floor, minimum=0.0, maximum=1.0, minimum_open=True
        )
        self.handover_length = check_float("handover_length", handover_length, minimum=0.0)
        self.probes_per_dim = check_float("probes_per_dim", probes_per_dim, minimum=0.0)
        self.probe_metric = check_choice("probe_metric", probe_metric, PROBE_METRICS)
        self.probe_scale = check_float("probe_scale", probe_scale, minimum=0.0, minimum_open=True)
        low, high = DEFAULT_BOUNDS if self.probe_metric == "euclidean" else KERNEL_PROBE_BOUNDS
        self._probe_bounds = (low * self.probe_scale, high * self.probe_scale)
        #: Probes per local phase, ``ceil(probes_per_dim * d)``.
        self.probes = int(np.ceil(self.probes_per_dim * self.dim))
        self._probes_left = 0
        self._asked_probe = False
        self._origin: np.ndarray | None = None  # the phase's probes' and steps' origin
        self._origin_scale = np.ones(self.dim)  # lengthscales of the fit that started it
        self.mode = "global"
        self._losses = 0  # consecutive losing local steps
        self._cooldown_left = 0
        self._asked_local = False
        self._fit_key: tuple[int, int] | None = None
        #: Mode of every ask after the initial design, in order (restart asks are "global").
        self.modes: list[str] = []
        #: ``z`` of every handover check, in order (inspection, tests).
        self.confidences: list[float] = []

    @property
    def origin(self) -> np.ndarray | None:
        """The current local phase's origin: its probes' center and its steps' start (module
        docstring); None without probes or outside a local phase."""
        return None if self._origin is None else self._origin.copy()

    # ------------------------------------------------------------------ model
    def _fit(self) -> Surrogate:
        """TuRPBO's refit, reused while no candidate or duel was added (the handover check
        and the global acquisition of one ask share a fit)."""
        key = (len(self._candidates), len(self._outcomes))
        if self._fit_key == key and self._refitter.surrogate is not None:
            return self._refitter.surrogate
        surrogate = super()._fit()
        self._fit_key = key
        return surrogate

    def _local_step(self, surrogate: Surrogate, center: np.ndarray) -> tuple[np.ndarray, float]:
        """The local step from ``center`` (unit step scale) and the slope confidence ``z``."""
        x = torch.tensor(center, dtype=torch.float64)
        g = surrogate.mean_gradient(x).detach().numpy()
        sigma = surrogate.gradient_covariance(x).detach().numpy()
        if self.local_direction == "newton":
            H = surrogate.mean_hessian(x).detach().numpy()
            if np.all(np.isfinite(H)) and np.all(np.isfinite(g)):
                u = -np.linalg.solve(negative_definite_modification(H, self.eigenvalue_floor), g)
            else:
                u = np.zeros_like(g)
        else:
            u = g
        if not (np.all(np.isfinite(u)) and np.all(np.isfinite(sigma))):
            return np.zeros_like(g), 0.0
        ls = surrogate.lengthscale.detach().numpy().reshape(-1)
        return kernel_normalized_step(u, ls, self.step_size), slope_confidence(g, u, sigma)

    # ------------------------------------------------------------------ ask
    def _propose(self, remaining: int) -> Ask:
        self._asked_local = False
        self._asked_probe = False
        if self._restart_pending:
            self.modes.append("global")
        return super()._propose(remaining)

    def _select(self, q: int, rng: np.random.Generator) -> np.ndarray:
        assert self._center_id is not None
        center = np.asarray(self._candidates[self._center_id].theta, dtype=np.float64)
        if self.mode == "local" and self._probes_left > 0:
            return self._probe(rng)
        surrogate = self._fit()
        origin = center if self._origin is None or self.mode == "global" else self._origin
        if self.mode == "local" or self._cooldown_left == 0:
            step, z = self._local_step(surrogate, origin)
            if self.mode == "global":
                self.confidences.append(z)
                if z >= self.confidence or self.tr.length <= self.handover_length:
                    self.mode = "local"
                    self._losses = 0
                    self._start_phase(center, surrogate)
                    if self._probes_left > 0:
                        return self._probe(rng)
        if self.mode == "local":
            point = np.clip(origin + step * 0.5**self._losses, 0.0, 1.0)
            if np.max(np.abs(point - center)) > DUPLICATE_ATOL:
                self._asked_local = True
                self.modes.append("local")
                return point[None, :]
            self._hand_back()
        self.modes.append("global")
        return super()._select(q, rng)

    def _start_phase(self, origin: np.ndarray, surrogate: Surrogate) -> None:
        """A local phase at ``origin``: its probes, then steps from it (module docstring);
        ``surrogate``'s lengthscales scale the probes in the kernel metric."""
        self._probes_left = self.probes
        self._origin = origin.copy() if self.probes > 0 else None
        self._origin_scale = surrogate.lengthscale.detach().numpy().reshape(-1).copy()

    def _probe(self, rng: np.random.Generator) -> np.ndarray:
        """One probe of the local phase (module docstring), as a one-row batch."""
        assert self._origin is not None
        self._asked_probe = True
        self.modes.append("probe")
        if self.probe_metric == "euclidean":
            return random_local_query(self._origin, rng, self._probe_bounds)[None, :]
        u = sphere_directions(1, self.dim, rng)[0]
        r = rng.uniform(*self._probe_bounds)
        return np.clip(self._origin + r * self._origin_scale * u, 0.0, 1.0)[None, :]

    # ------------------------------------------------------------------ tell
    def _hand_back(self) -> None:
        self.mode = "global"
        self._losses = 0
        self._probes_left = 0
        self._origin = None
        self._cooldown_left = self.cooldown

    def _on_step_complete(
        self, candidates: tuple[Candidate, ...], outcomes: tuple[DuelAnswer, ...]
    ) -> None:
        was_restart = self._restart_pending
        super()._on_step_complete(candidates, outcomes)
        if was_restart:  # the fresh point of a restart: no trust-region iteration
            return
        last = self.region_history[-1]
        if self._restart_pending:
            self._hand_back()
            self._cooldown_left = 0
            return
        if self._asked_probe:
            self._probes_left -= 1
        elif self._asked_local:
            if last.success:
                self._losses = 0
                assert self._center_id is not None
                surrogate = self._refitter.surrogate  # the fit of this step's ask
                assert surrogate is not None
                self._start_phase(np.asarray(self._candidates[self._center_id].theta), surrogate)
            else:
                self._losses += 1
                if self._losses >= self.stall_duels:
                    self._hand_back()
        elif self._cooldown_left > 0:
            self._cooldown_left -= 1
