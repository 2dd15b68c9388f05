"""The surrogate contract: what the optimizers may ask of a fitted preference model.

A :class:`Surrogate` is a *fitted* Laplace-approximated pairwise GP (paper Sec. 4) with an
ARD squared-exponential prior ``k(x, x') = s exp(-0.5 (x - x')^T Lambda (x - x'))``,
``Lambda = diag(1 / l^2)``, on inputs in ``[0, 1]^d``. Its posterior over the latent utility
``f`` is Gaussian,

    ``mu(x) = k(x, X) K^{-1} f_hat``,
    ``cov(x, x') = k(x, x') - k(x, X) (K + C_hat^{-1})^{-1} k(X, x')``,

with ``f_hat`` the MAP of the utility at the unique training points ``X`` ``(p, d)``, ``C``
the Hessian of the negative log likelihood at the MAP (paper eq. (8), the matrix C) and
``C_hat = C + eps_reg I``; derivatives of ``f`` follow from the joint predictive of values and
derivatives (paper eq. (10)) with covariance blocks of eq. (11).

Conventions shared by every method: tensors are ``torch.float64``; a point argument is either
one point ``(d,)`` (the result drops the leading batch axis) or a batch ``(N, d)``; points lie in
``[0, 1]^d``. Nothing here refits: a surrogate is immutable once fitted, and a new fit
(:meth:`PairwiseGPSurrogate.fit`) may take the previous one as a warm start.

:class:`~localpbo_core.surrogate.pairwise_gp.PairwiseGPSurrogate` implements it.
"""

from __future__ import annotations

from typing import Protocol

import numpy as np
import torch
from torch import Tensor

from .ordinal import Ordinal
from .sampling import SamplePaths


class Surrogate(Protocol):
    """A fitted pairwise-GP posterior over the latent utility (see the module docstring).

    Attributes:
        train_inputs: ``(p, d)`` unique training points ``X`` in ``[0, 1]^d``.
        winners, losers: ``(m,)`` int64 indices into ``train_inputs``: duel ``n`` says
            ``X[winners[n]]`` was preferred to ``X[losers[n]]``.
        utility: ``(p,)`` the MAP ``f_hat`` at ``train_inputs``.
        lengthscale: ``(d,)`` ARD lengthscales ``l`` (positive).
        outputscale: the prior variance ``s`` (positive).
        eps_reg: ``>= 0``; the posterior covariances use ``C_hat = C + eps_reg I``.
        z_limit: ``|z|`` clamp of the probit likelihood, or None for the exact probit.
        jitter: relative diagonal jitter added to ``K`` (``K + jitter s I``).
        fit_curvature: ``(h, h)`` curvature of the hyperparameter objective at the fit
            (``h`` learned log-hyperparameters), or None; a warm-started fit starts from it.
        tie: ``(m,)`` bool: duel rows that are "can't tell" answers (then ``winners[n]``,
            ``losers[n]`` are the duel's first and second point).
        tie_threshold: the indifference threshold ``eps >= 0`` of the ordinal likelihood
            (:mod:`.ordinal`); 0 is the paper's probit.
        ordinal: the :class:`.ordinal.Ordinal` likelihood, or None for the paper's probit.
    """

    train_inputs: Tensor
    winners: Tensor
    losers: Tensor
    utility: Tensor
    lengthscale: Tensor
    outputscale: float
    eps_reg: float
    z_limit: float | None
    jitter: float
    tie: Tensor
    tie_threshold: float
    ordinal: Ordinal | None
    fit_curvature: np.ndarray | None

    @property
    def dim(self) -> int:
        """``d``, the input dimension."""
        ...

    @property
    def chol_K(self) -> Tensor:
        """``(p, p)`` lower Cholesky factor ``L`` of ``K + jitter s I`` at ``train_inputs``."""
        ...

    @property
    def chol_B(self) -> Tensor:
        """``(p, p)`` lower Cholesky factor ``L_B`` of ``B = I + L^T C_hat L``."""
        ...

    @property
    def likelihood_hessian(self) -> Tensor:
        """``(p, p)`` the matrix ``C`` of paper eq. (8) at the MAP (without ``eps_reg``)."""
        ...

    def mean(self, x: Tensor) -> Tensor:
        """``mu(x)``: 0-d for ``(d,)``, ``(N,)`` for ``(N, d)``. Differentiable in ``x``."""
        ...

    def mean_gradient(self, x: Tensor) -> Tensor:
        """``grad mu(x)``: ``(d,)`` for ``(d,)``, ``(N, d)`` for ``(N, d)``."""
        ...

    def mean_hessian(self, x: Tensor) -> Tensor:
        """``hess mu(x)``: ``(d, d)`` for ``(d,)``, ``(N, d, d)`` for ``(N, d)``."""
        ...

    def gradient_covariance(self, x: Tensor, eps_reg: float | None = None) -> Tensor:
        """Posterior covariance ``Sigma_11(x)`` of ``grad f(x)`` (paper eq. (15), the
        pairwise-GP Jacobian variance): ``(d, d)`` or ``(N, d, d)``. ``eps_reg`` overrides
        the fit's value (None keeps it)."""
        ...

    def posterior_mean_cov(self, Xq: Tensor) -> tuple[Tensor, Tensor]:
        """Joint posterior of ``f`` at ``Xq`` ``(q, d)``: mean ``(q,)`` and covariance
        ``(q, q)``. Differentiable in ``Xq``."""
        ...

    def preference_probability(self, x: Tensor, x2: Tensor) -> Tensor:
        """``P(x preferred to x2)`` under the posterior and the probit likelihood (paper
        eq. (5)) with unit noise, in ``[0, 1]``: 0-d for ``(d,)`` inputs, ``(N,)`` for
        row-paired ``(N, d)`` inputs."""
        ...

    def sample_paths(
        self, num_paths: int, generator: torch.Generator, num_features: int = 1024
    ) -> SamplePaths:
        """``num_paths`` posterior sample paths ``(N, d) -> (N, num_paths)``, deterministic
        given ``generator`` (see :class:`~localpbo_core.surrogate.sampling.SamplePaths`)."""
        ...
