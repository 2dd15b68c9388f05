"""The surrogate refit policy shared by the GP-based optimizers (TuRPBO, qEUBO).

Every iteration refits the pairwise GP on all comparisons so far, warm-started from the
previous fit (paper Alg. "TurPBO", line "Fit pairwise GP model using D_t"). Hyperparameters
are relearned (Laplace evidence, paper Sec. 4) at every ``every``-th fit and held fixed in
between; ``every = 1`` (the default everywhere) is the paper's behaviour, larger values are a
documented speed option.
"""

from __future__ import annotations

import numpy as np
import torch

from localpbo_core.surrogate import PairwiseGPSurrogate, Surrogate
from localpbo_core.validation import check_int


class SurrogateRefitter:
    """Owns the latest surrogate and refits it by the policy above.

    Args:
        every: relearn hyperparameters at fits 0, k, 2k, ...; must be an integer >= 1.
    """

    def __init__(self, every: int = 1) -> None:
        self.every = check_int("hyperparameter_refit_every", every)
        self.fits = 0
        self.surrogate: Surrogate | None = None

    def refit(self, train_inputs: np.ndarray, comparisons: np.ndarray) -> Surrogate:
        """Fit on ``train_inputs`` (n, d) in [0,1]^d and ``comparisons`` (m, 2) [winner, loser]."""
        X = torch.tensor(train_inputs, dtype=torch.float64)
        comps = torch.tensor(comparisons, dtype=torch.long)
        prev = self.surrogate
        if prev is not None and self.fits % self.every != 0:
            fitted = PairwiseGPSurrogate.fit(
                X,
                comps,
                lengthscale=prev.lengthscale,
                outputscale=prev.outputscale,
                warm_start=prev,
            )
        else:
            fitted = PairwiseGPSurrogate.fit(X, comps, warm_start=prev)
        self.surrogate = fitted
        self.fits += 1
        return fitted
