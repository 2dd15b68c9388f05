"""Which evaluated candidate to hand to the user at the end of a run.

An optimizer's ``incumbent`` is its king of the hill: the last candidate that won its duel
against the previous incumbent. Under noisy preferences (paper eqs. (2) "observation noise"
and (3) "preference") one lucky win can crown a worse candidate, and a run of them walks the
incumbent down. The recommendation instead
weighs every duel of the run: it fits the pairwise GP of paper Sec. 4 (Laplace posterior,
hyperparameters learned from the evidence) to all comparisons and returns the evaluated
candidate with the highest posterior mean utility ``mu(x) = k(x, X) K^{-1} f_hat``. It reads
only the preferences, never a return. When the optimizer keeps a fitted surrogate, the fit is
warm-started from it. "Can't tell" answers enter with the optimizer's ``tie_threshold``
(the ordinal likelihood of :mod:`localpbo_core.surrogate.ordinal`).
"""

from __future__ import annotations

import numpy as np
import torch

from localpbo_core.optimizers.base import Candidate
from localpbo_core.optimizers.preference_optimizer import PreferenceOptimizer
from localpbo_core.surrogate import PairwiseGPSurrogate


def recommend(optimizer: PreferenceOptimizer) -> Candidate | None:
    """The evaluated candidate with the highest posterior mean utility given all duels so far
    (ties: lowest id); the incumbent while there is no outcome yet (None before any)."""
    comparisons = optimizer.comparisons()
    ties = optimizer.ties()
    if comparisons.shape[0] == 0 and ties.shape[0] == 0:
        return optimizer.incumbent
    X = torch.tensor(optimizer.train_inputs(), dtype=torch.float64)
    # the optimizer's own last fit (TuRPBO, qEUBO, ...) is a warm start: one refit, not a cold fit
    warm = optimizer.surrogate
    if warm is not None and warm.dim != X.shape[1]:
        warm = None
    surrogate = PairwiseGPSurrogate.fit(
        X,
        torch.tensor(comparisons, dtype=torch.long),
        warm_start=warm,
        ties=torch.tensor(ties, dtype=torch.long),
        tie_threshold=optimizer.tie_threshold,
    )
    with torch.no_grad():
        mean = surrogate.mean(X).numpy()
    best = int(np.argmax(mean))  # first maximum: the lowest id
    return optimizer.history.candidates[best]
