"""The base of qEUBO and TuRPBO: every iteration refits the pairwise GP on all duels and
maximises an acquisition over raw samples and multistart L-BFGS-B restarts.

The refit is :class:`~localpbo_core.optimizers.surrogate_refit.SurrogateRefitter`'s (paper
Alg. "TurPBO", line "Fit pairwise GP model using D_t"; hyperparameters learned on the Laplace
evidence of Sec. 4 unless fixed); the restarts start from the best raw samples
(:func:`~localpbo_core.optimizers.preference_optimizer.check_multistart`). Both algorithms
share the PairwiseGP settings of App. D.1: 1024 raw samples and 5 restarts.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Unpack

from localpbo_core.optimizers.preference_optimizer import (
    PreferenceOptimizer,
    RunOptions,
    check_multistart,
)
from localpbo_core.optimizers.surrogate_refit import SurrogateRefitter
from localpbo_core.surrogate.protocol import Surrogate
from localpbo_core.validation import check_int


class GPAcquisitionOptions(RunOptions, total=False):
    """:class:`RunOptions` and the options of :class:`GPAcquisitionOptimizer`."""

    batch_size: int
    num_raw_samples: int
    num_restarts: int
    hyperparameter_refit_every: int
    hyperparameters: Mapping[str, object] | None


class GPAcquisitionOptimizer(PreferenceOptimizer):
    """Base of the optimizers that refit the pairwise GP every iteration and maximise an
    acquisition by multistart (module docstring); subclasses implement the ask/tell hooks.

    Args:
        dim, seed, budget, initial_design, warm_start: see ``PreferenceOptimizer``.
        batch_size: q >= 1 new points per iteration (paper: 1).
        num_raw_samples: raw samples of the acquisition maximisation (table: 1024).
        num_restarts: L-BFGS-B restarts from the best raw samples (table: 5).
        hyperparameter_refit_every: k >= 1. Default 1 (faithful): learn the GP
            hyperparameters at every iteration. With k > 1 they are learned at every k-th
            iteration only and held at the last learned values in between (the Laplace MAP
            is still refit on all data every iteration). A speed option, not the paper's.
        hyperparameters: fixed GP hyperparameters (App. D.4 within-model runs; see
            :mod:`~localpbo_core.optimizers.surrogate_refit`). Default None: learned.
    """

    def __init__(
        self,
        dim: int,
        seed: int,
        budget: int,
        batch_size: int = 1,
        num_raw_samples: int = 1024,
        num_restarts: int = 5,
        hyperparameter_refit_every: int = 1,
        hyperparameters: Mapping[str, object] | None = None,
        **run: Unpack[RunOptions],
    ) -> None:
        super().__init__(dim, seed, budget, **run)
        self.batch_size = check_int("batch_size", batch_size)
        self.num_restarts, self.num_raw_samples = check_multistart(num_restarts, num_raw_samples)
        self._refitter = SurrogateRefitter.for_options(
            hyperparameter_refit_every, hyperparameters, self.dim, self.tie_threshold
        )
        self.hyperparameter_refit_every = self._refitter.every

    @property
    def surrogate(self) -> Surrogate | None:
        """The last fitted surrogate (None before the first iteration)."""
        return self._refitter.surrogate

    def _fit(self) -> Surrogate:
        return self._refitter.refit(self.train_inputs(), self.comparisons(), self.ties())
