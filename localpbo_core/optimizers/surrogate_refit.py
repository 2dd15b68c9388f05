"""The surrogate refit policy shared by the GP-based optimizers (TuRPBO, qEUBO, GIPBO,
GIPBOr, PrefSQP).

Every iteration refits the pairwise GP on all comparisons so far, warm-started from the
previous fit (paper Alg. "TurPBO", line "Fit pairwise GP model using D_t"). Hyperparameters
are relearned (Laplace evidence, paper Sec. 4) at every ``every``-th fit and held fixed in
between; ``every = 1`` (the default everywhere) is the paper's behaviour, larger values are a
documented speed option.

**Fixed hyperparameters** (the paper's *within-model* runs on GP sample paths, App. D.4: the
optimizers get the true hyperparameters). Every model-based algorithm takes the option
``hyperparameters={"lengthscale": l, "outputscale": s}`` (either key may be left out; a left
out one is learned). It is checked by :func:`check_hyperparameters` and applied here, at every
fit: the surrogate's hyperparameters then equal the given values after every fit. ``l`` is a
positive number (isotropic) or a sequence of ``d`` positive numbers (ARD), ``s`` a positive
number; they need not lie in the learning bounds.

**"Can't tell" answers**: ``refit`` takes the ties as ``(k, 2)`` ``[first, second]`` rows and the
refitter's ``tie_threshold`` (the ordinal likelihood's ``eps``,
:mod:`localpbo_core.surrogate.ordinal`); with ``tie_threshold = 0`` and no ties the fit is the
paper's.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
import torch

from localpbo_core.surrogate import PairwiseGPSurrogate, Surrogate
from localpbo_core.validation import SettingError, check_float, check_int

HYPERPARAMETER_KEYS = ("lengthscale", "outputscale")
"""Keys of the ``hyperparameters`` option."""


@dataclass(frozen=True)
class FixedHyperparameters:
    """Validated fixed hyperparameters (None: learned)."""

    lengthscale: tuple[float, ...] | None = None
    outputscale: float | None = None


def check_hyperparameters(value: object, dim: int) -> FixedHyperparameters | None:
    """The ``hyperparameters`` option as :class:`FixedHyperparameters` (None for None).

    Raises:
        SettingError: field ``hyperparameters`` or ``hyperparameters.<key>``.
    """
    if value is None:
        return None
    if not isinstance(value, Mapping) or not value:
        raise SettingError(
            "hyperparameters",
            f"must be a non-empty mapping with keys {HYPERPARAMETER_KEYS}, got {value!r}",
        )
    for key in value:
        if key not in HYPERPARAMETER_KEYS:
            raise SettingError(
                f"hyperparameters.{key}", f"unknown key; valid: {', '.join(HYPERPARAMETER_KEYS)}"
            )
    lengthscale: tuple[float, ...] | None = None
    if "lengthscale" in value:
        raw = value["lengthscale"]
        field = "hyperparameters.lengthscale"
        if isinstance(raw, list | tuple | np.ndarray):
            if len(raw) != dim:
                raise SettingError(field, f"expected a number or {dim} numbers, got {len(raw)}")
            lengthscale = tuple(check_float(field, v, minimum=0.0, minimum_open=True) for v in raw)
        else:
            ls = check_float(field, raw, minimum=0.0, minimum_open=True)
            lengthscale = (ls,) * dim
    outputscale = None
    if "outputscale" in value:
        outputscale = check_float(
            "hyperparameters.outputscale", value["outputscale"], minimum=0.0, minimum_open=True
        )
    return FixedHyperparameters(lengthscale, outputscale)


class SurrogateRefitter:
    """Owns the latest surrogate and refits it by the policy above.

    Args:
        every: relearn hyperparameters at fits 0, k, 2k, ...; must be an integer >= 1.
        fixed: hyperparameters held at given values at every fit (:func:`check_hyperparameters`).
        tie_threshold: the indifference threshold ``eps >= 0`` of the ordinal likelihood.
    """

    def __init__(
        self,
        every: int = 1,
        fixed: FixedHyperparameters | None = None,
        tie_threshold: float = 0.0,
    ) -> None:
        self.every = check_int("hyperparameter_refit_every", every)
        self.fixed = fixed
        self.tie_threshold = check_float("tie_threshold", tie_threshold, minimum=0.0)
        self.fits = 0
        self.surrogate: Surrogate | None = None

    @classmethod
    def for_options(
        cls, every: int, hyperparameters: object, dim: int, tie_threshold: float
    ) -> SurrogateRefitter:
        """The refitter of an optimizer's options ``hyperparameter_refit_every`` and
        ``hyperparameters`` (checked by :func:`check_hyperparameters` for ``dim``)."""
        return cls(every, check_hyperparameters(hyperparameters, dim), tie_threshold)

    def refit(
        self,
        train_inputs: np.ndarray,
        comparisons: np.ndarray,
        ties: np.ndarray | None = None,
    ) -> Surrogate:
        """Fit on ``train_inputs`` (n, d) in [0,1]^d, ``comparisons`` (m, 2) [winner, loser]
        and the "can't tell" ``ties`` (k, 2) [first, second] (None or empty: none)."""
        X = torch.tensor(train_inputs, dtype=torch.float64)
        comps = torch.tensor(comparisons, dtype=torch.long).reshape(-1, 2)
        tie_rows = None
        if ties is not None and len(ties):
            tie_rows = torch.tensor(ties, dtype=torch.long).reshape(-1, 2)
        prev = self.surrogate
        lengthscale: torch.Tensor | None = None
        outputscale: float | None = None
        if prev is not None and self.fits % self.every != 0:
            lengthscale, outputscale = prev.lengthscale, prev.outputscale
        if self.fixed is not None:
            if self.fixed.lengthscale is not None:
                lengthscale = torch.tensor(self.fixed.lengthscale, dtype=torch.float64)
            if self.fixed.outputscale is not None:
                outputscale = self.fixed.outputscale
        if lengthscale is None and outputscale is None:
            fitted = PairwiseGPSurrogate.fit(
                X, comps, warm_start=prev, ties=tie_rows, tie_threshold=self.tie_threshold
            )
        else:
            fitted = PairwiseGPSurrogate.fit(
                X,
                comps,
                lengthscale=lengthscale,
                outputscale=outputscale,
                warm_start=prev,
                ties=tie_rows,
                tie_threshold=self.tie_threshold,
            )
        self.surrogate = fitted
        self.fits += 1
        return fitted
