"""Sobol baseline (paper Sec. 6, baselines table of App. D.1).

After the shared initial design, points of a scrambled Sobol sequence are proposed in
order and each is dueled against the incumbent (king of the hill, App. D.1).
"""

from __future__ import annotations

import warnings
from typing import Unpack

import numpy as np
from scipy.stats import qmc

from localpbo_core.optimizers.preference_optimizer import BatchOptions, KingOfTheHillOptimizer

#: Tag mixed into the seed of the Sobol scrambling.
SOBOL_TAG = 0x5B01


class SobolOptimizer(KingOfTheHillOptimizer):
    """Scrambled, seeded Sobol sequence dueled against the incumbent.

    Args:
        dim, seed, budget, initial_design, warm_start: see ``PreferenceOptimizer``.
        batch_size: Sobol points proposed per ask (each dueled against the incumbent).
    """

    name = "sobol"

    def __init__(self, dim: int, seed: int, budget: int, **options: Unpack[BatchOptions]) -> None:
        super().__init__(dim, seed, budget, **options)
        rng = np.random.default_rng(np.random.SeedSequence([self.seed, SOBOL_TAG]))
        self._engine = qmc.Sobol(d=self.dim, scramble=True, rng=rng)

    def _propose_thetas(self, q: int) -> list[np.ndarray]:
        # Sobol balance warnings for non-powers of two are irrelevant for a sequential stream.
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", category=UserWarning)
            pts = self._engine.random(q)
        return list(pts)
