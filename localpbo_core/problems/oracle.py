"""The noisy preference oracle of the paper (Sec. 3, eq. noise and eq. pi).

A comparison of values ``f_a`` and ``f_b`` observes ``y_a = f_a + eps_a`` and
``y_b = f_b + eps_b`` with ``eps_a, eps_b ~ N(0, sigma_n^2)`` i.i.d. (eq. noise) and reports
whether ``y_a > y_b`` (eq. pi: ``pi = 0``, the first input preferred, iff ``y_a > y_b``; ties
go to the second). ``sigma_n = noise_fraction * problem.value_range`` with
``noise_fraction = 0.1`` by default (paper Sec. 6 and App. D.1, "Noise model").

The noise comes from ``numpy.random.default_rng(seed)``: two standard normals per comparison
(first for a, then for b), so outcomes are deterministic given the seed and the call order.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from ._validation import check_seed
from .base import Problem


class Duel(NamedTuple):
    """Outcome of ``PreferenceOracle.duel``: whether a won, and the two evaluated values."""

    a_wins: bool
    value_a: float
    value_b: float


class PreferenceOracle:
    """Noisy pairwise comparisons of problem values (paper eq. noise / eq. pi).

    Args:
        problem: supplies ``value_range`` (and ``evaluate`` for ``duel``).
        noise_fraction: noise std as a fraction of ``problem.value_range`` (>= 0; 0 gives a
            noise-free oracle that always prefers the larger value).
        seed: seed of the oracle's own noise generator.
    """

    def __init__(self, problem: Problem, noise_fraction: float = 0.1, seed: int = 0) -> None:
        if (
            isinstance(noise_fraction, bool)
            or not isinstance(noise_fraction, int | float)
            or not math.isfinite(noise_fraction)
        ):
            raise ValueError(f"noise_fraction: expected a finite number, got {noise_fraction!r}")
        if noise_fraction < 0:
            raise ValueError(f"noise_fraction: must be >= 0, got {noise_fraction!r}")
        value_range = float(problem.value_range)
        if noise_fraction > 0 and not (math.isfinite(value_range) and value_range > 0):
            raise ValueError(
                f"value_range: problem {problem.name!r} has value_range {value_range!r}; "
                "a positive finite range is needed for noise_fraction > 0"
            )
        self.problem = problem
        self.noise_fraction = float(noise_fraction)
        self.noise_std = self.noise_fraction * value_range if noise_fraction > 0 else 0.0
        self.seed = check_seed(seed)
        self._rng = np.random.default_rng(self.seed)
        self.comparisons = 0

    def noisy_pair(self, value_a: float, value_b: float) -> tuple[float, float]:
        """The noisy observations ``(y_a, y_b)`` of eq. noise (advances the generator)."""
        for label, value in (("value_a", value_a), ("value_b", value_b)):
            if not math.isfinite(float(value)):
                raise ValueError(f"{label}: expected a finite value, got {value!r}")
        eps = self._rng.standard_normal(2)
        self.comparisons += 1
        y_a = float(value_a) + self.noise_std * float(eps[0])
        y_b = float(value_b) + self.noise_std * float(eps[1])
        return y_a, y_b

    def compare(self, value_a: float, value_b: float) -> bool:
        """True if a wins: ``y_a > y_b`` under the noise of eq. noise (eq. pi)."""
        y_a, y_b = self.noisy_pair(value_a, value_b)
        return bool(y_a > y_b)

    def duel(self, theta_a: np.ndarray, seed_a: int, theta_b: np.ndarray, seed_b: int) -> Duel:
        """Evaluate both thetas (one seeded evaluation each), then ``compare`` the values."""
        value_a = self.problem.evaluate(theta_a, seed_a)
        value_b = self.problem.evaluate(theta_b, seed_b)
        return Duel(self.compare(value_a, value_b), value_a, value_b)
