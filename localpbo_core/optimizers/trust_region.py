"""TuRPBO trust-region state machine and geometry (paper Sec. 5.3, App. C.5, Alg. TurPBO).

The rules are TuRBO's (Eriksson et al., 2019) with the preferential success test of
App. C.5: an iteration succeeds iff some batch candidate is preferred to the incumbent.
Hyperparameters follow the TuRPBO hyperparameter table of App. C.5: ``L_init = 0.8``,
``L_min = 0.5**7``, ``L_max = 1.6``, ``tau_succ = d``, ``tau_fail = ceil(max(4/q, d/q))``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import Enum

import numpy as np
from scipy.stats import qmc


class TREvent(Enum):
    """What an update did to the trust region."""

    NONE = "none"
    EXPAND = "expand"
    SHRINK = "shrink"
    RESTART = "restart"


@dataclass(frozen=True)
class TRStep:
    """One iteration of Alg. TurPBO as it happened: the side length ``length`` the batch was
    proposed in, whether some candidate beat the center (``success``), and what the update
    then did to the region (``event``)."""

    length: float
    success: bool
    event: TREvent


@dataclass
class TrustRegionState:
    """Side length and counters of Alg. TurPBO (App. C.5).

    Attributes:
        dim: problem dimension d.
        batch_size: q.
        length: current side length L.
        success_counter, failure_counter: consecutive successes / failures.
        restarts: number of restarts so far.
    """

    dim: int
    batch_size: int = 1
    length_init: float = 0.8
    length_min: float = 0.5**7
    length_max: float = 1.6
    length: float = 0.8
    success_counter: int = 0
    failure_counter: int = 0
    restarts: int = 0

    @property
    def success_tolerance(self) -> int:
        """tau_succ = d (TuRPBO table; not TuRBO's 3)."""
        return self.dim

    @property
    def failure_tolerance(self) -> int:
        """tau_fail = ceil(max(4/q, d/q)) (TuRPBO table)."""
        return math.ceil(max(4.0 / self.batch_size, self.dim / self.batch_size))

    def update(self, success: bool) -> TREvent:
        """Apply one iteration of Alg. TurPBO lines 8-24 and return what happened.

        On success: c_succ += 1, c_fail = 0; on failure: c_fail += 1, c_succ = 0. After
        tau_succ successes L <- min(2L, L_max); after tau_fail failures L <- L/2 (counters
        reset). If L < L_min the region restarts: L <- L_init, counters reset.
        """
        if success:
            self.success_counter += 1
            self.failure_counter = 0
        else:
            self.failure_counter += 1
            self.success_counter = 0
        event = TREvent.NONE
        if self.success_counter == self.success_tolerance:
            self.length = min(2.0 * self.length, self.length_max)
            self.success_counter = 0
            self.failure_counter = 0
            event = TREvent.EXPAND
        elif self.failure_counter == self.failure_tolerance:
            self.length = self.length / 2.0
            self.success_counter = 0
            self.failure_counter = 0
            event = TREvent.SHRINK
        if self.length < self.length_min:
            self.length = self.length_init
            self.success_counter = 0
            self.failure_counter = 0
            self.restarts += 1
            event = TREvent.RESTART
        return event


def trust_region_bounds(
    center: np.ndarray, lengthscale: np.ndarray, length: float
) -> tuple[np.ndarray, np.ndarray]:
    """TuRBO's lengthscale-weighted box (App. C.5: "trust-region geometry ... unchanged").

    Weights ``w = l / prod(l)^(1/d)`` (geometric mean 1, so the box volume is ``L^d``);
    box ``center +- w L / 2`` clipped to [0,1]^d.
    """
    ls = np.asarray(lengthscale, dtype=np.float64).reshape(-1)
    if ls.shape != center.shape:
        raise ValueError(f"lengthscale: expected shape {center.shape}, got {ls.shape}")
    weights = ls / np.exp(np.mean(np.log(ls)))
    lb = np.clip(center - weights * length / 2.0, 0.0, 1.0)
    ub = np.clip(center + weights * length / 2.0, 0.0, 1.0)
    return lb, ub


def perturbed_candidates(
    center: np.ndarray,
    lb: np.ndarray,
    ub: np.ndarray,
    num: int,
    rng: np.random.Generator,
) -> np.ndarray:
    """TuRBO's raw Thompson candidates: Sobol points in the box, where each coordinate is
    taken from the Sobol point with probability ``min(20/d, 1)`` and otherwise kept at the
    center (at least one coordinate per point is perturbed)."""
    d = center.size
    sobol = qmc.Sobol(d=d, scramble=True, rng=rng)
    pert = lb + (ub - lb) * sobol.random(num)
    prob = min(20.0 / d, 1.0)
    mask = rng.random((num, d)) <= prob
    empty = ~mask.any(axis=1)
    if empty.any():
        mask[np.flatnonzero(empty), rng.integers(0, d, size=int(empty.sum()))] = True
    return np.where(mask, pert, center[None, :])
