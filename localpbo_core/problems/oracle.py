"""The noisy preference oracle of the paper (Sec. 2, eqs. (2) and (3)).

A comparison of values ``f_a`` and ``f_b`` observes ``y_a = f_a + eps_a`` and
``y_b = f_b + eps_b`` with ``eps_a, eps_b ~ N(0, sigma_n^2)`` i.i.d. (eq. (2), the observation
noise) and reports whether ``y_a > y_b`` (eq. (3): the first input is preferred iff
``y_a > y_b``; ties go to the second). ``sigma_n = noise_fraction * problem.value_range`` with
``noise_fraction = 0.1`` by default (paper Sec. 6 and App. D.1, "Noise model").

Two forms, the same noise model:

* :class:`DuelOracle`, used by every run of localpbo: duel ``k`` of a run draws its two
  standard normals (first for a, then for b) from a generator seeded by
  ``localpbo_core.seeds.duel_seed(run seed, k)``, so an answer depends on the run seed, the
  duel id and the two values only, whichever process answers it and in whichever order;
* :class:`PreferenceOracle`, one generator for a sequence of comparisons (deterministic given
  the seed and the call order), for studies of the noise model itself.

"Can't tell": a :class:`DuelOracle` with ``indifference = q > 0`` answers neither (a tie) when
``|y_first - y_second| < q * value_range``, a judge who cannot separate close outcomes (the
ordinal model of :mod:`localpbo_core.surrogate.ordinal` with an unknown threshold). The same
two normals are drawn, so the decisive answers are those of ``q = 0``.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from localpbo_core.seeds import duel_seed
from localpbo_core.settings import DEFAULT_NOISE_FRACTION
from localpbo_core.validation import SettingError, check_float, check_int

from .base import Problem


class Comparison(NamedTuple):
    """Result of ``PreferenceOracle.duel``: whether a won, and the two evaluated values."""

    a_wins: bool
    value_a: float
    value_b: float


class PreferenceOracle:
    """Noisy pairwise comparisons of problem values (paper Sec. 2, eqs. (2)-(3)).

    Args:
        problem: supplies ``value_range`` (and ``evaluate`` for ``duel``).
        noise_fraction: noise std as a fraction of ``problem.value_range`` (>= 0; 0 gives a
            noise-free oracle that always prefers the larger value).
        seed: seed of the oracle's own noise generator.
    """

    def __init__(
        self, problem: Problem, noise_fraction: float = DEFAULT_NOISE_FRACTION, seed: int = 0
    ) -> None:
        self.problem = problem
        self.noise_fraction = float(noise_fraction)
        self.noise_std = noise_std(problem, noise_fraction)
        self.seed = check_int("seed", seed, minimum=0)
        self._rng = np.random.default_rng(self.seed)
        self.comparisons = 0

    def noisy_pair(self, value_a: float, value_b: float) -> tuple[float, float]:
        """The noisy observations ``(y_a, y_b)`` of paper eq. (2) (advances the generator)."""
        pair = _noisy_pair(self.noise_std, self._rng, value_a, value_b)
        self.comparisons += 1
        return pair

    def compare(self, value_a: float, value_b: float) -> bool:
        """True if a wins: ``y_a > y_b`` under the noise of paper eq. (2) (eq. (3))."""
        y_a, y_b = self.noisy_pair(value_a, value_b)
        return bool(y_a > y_b)

    def duel(
        self, theta_a: np.ndarray, seed_a: int, theta_b: np.ndarray, seed_b: int
    ) -> Comparison:
        """Evaluate both thetas (one seeded evaluation each), then ``compare`` the values."""
        value_a = self.problem.evaluate(theta_a, seed_a)
        value_b = self.problem.evaluate(theta_b, seed_b)
        return Comparison(self.compare(value_a, value_b), value_a, value_b)


class DuelOracle:
    """The oracle of a run: duel ``k`` draws its noise from ``duel_seed(run_seed, k)``.

    Args:
        problem: supplies ``value_range``.
        noise_fraction: noise std as a fraction of ``problem.value_range`` (>= 0).
        run_seed: the run seed.
        indifference: answer "can't tell" when ``|y_first - y_second|`` is below this
            fraction of ``problem.value_range`` (>= 0; 0 never, the paper's oracle).
    """

    def __init__(
        self,
        problem: Problem,
        noise_fraction: float = DEFAULT_NOISE_FRACTION,
        run_seed: int = 0,
        indifference: float = 0.0,
    ) -> None:
        self.noise_fraction = float(noise_fraction)
        self.noise_std = noise_std(problem, noise_fraction)
        self.run_seed = check_int("run_seed", run_seed, minimum=0)
        self.indifference = check_float("indifference", indifference, minimum=0.0)
        self.tie_width = 0.0
        if self.indifference > 0:
            self.tie_width = self.indifference * _value_range(problem, "indifference")

    def _observed(
        self, duel_id: int, value_first: float, value_second: float
    ) -> tuple[float, float]:
        """The two noisy values of duel ``duel_id`` (eq. (2)), drawn from its own seed."""
        rng = np.random.default_rng(duel_seed(self.run_seed, duel_id))
        return _noisy_pair(self.noise_std, rng, value_first, value_second)

    def first_wins(self, duel_id: int, value_first: float, value_second: float) -> bool:
        """True if the first candidate of duel ``duel_id`` is preferred (eq. (3))."""
        y_first, y_second = self._observed(duel_id, value_first, value_second)
        return bool(y_first > y_second)

    def judge(self, duel_id: int, value_first: float, value_second: float) -> bool | None:
        """True if the first candidate is preferred, False if the second, None for "can't
        tell" (``|y_first - y_second| < indifference * value_range``; never when
        ``indifference`` is 0, where this is :meth:`first_wins`)."""
        y_first, y_second = self._observed(duel_id, value_first, value_second)
        if abs(y_first - y_second) < self.tie_width:
            return None
        return bool(y_first > y_second)


def noise_std(problem: Problem, noise_fraction: float) -> float:
    """``noise_fraction * problem.value_range`` (0 for a noise-free oracle).

    Raises:
        SettingError: ``noise_fraction`` is not a finite number >= 0, or is > 0 for a problem
            without a positive finite value range.
    """
    fraction = check_float("noise_fraction", noise_fraction, minimum=0.0)
    if fraction == 0:
        return 0.0
    value_range = _value_range(problem, "noise_fraction", " (set the problem's value_range)")
    return fraction * value_range


def _value_range(problem: Problem, field: str, hint: str = "") -> float:
    """``problem.value_range``, which option ``field`` needs positive and finite (SettingError
    on ``field`` otherwise, ending with ``hint``)."""
    value_range = float(problem.value_range)
    if not (math.isfinite(value_range) and value_range > 0):
        raise SettingError(
            field,
            f"needs a positive finite value range; problem {problem.name!r} has "
            f"{value_range!r}{hint}",
        )
    return value_range


def _noisy_pair(
    std: float, rng: np.random.Generator, value_a: float, value_b: float
) -> tuple[float, float]:
    """``(y_a, y_b)`` of eq. (2): two standard normals from ``rng``, first for a."""
    for label, value in (("value_a", value_a), ("value_b", value_b)):
        check_float(label, value)
    eps = rng.standard_normal(2)
    return float(value_a) + std * float(eps[0]), float(value_b) + std * float(eps[1])
