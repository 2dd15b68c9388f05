"""A BoTorch ``Model`` view of :class:`~localpbo_core.surrogate.PairwiseGPSurrogate`.

BoTorch's preference acquisitions (EUBO, Lin et al. 2022; qEUBO, Astudillo et al. 2023; the
qEUBO baseline of paper Sec. 6 / App. D.1) only need ``model.posterior(X)`` — the joint
Laplace posterior of the latent utility at the ``q`` points of each t-batch (paper Sec. 4,
eq. (11) "general covariance block" with a = b = 0):

``mean = K(Xq, X) K^{-1} f_hat``,
``cov = K(Xq, Xq) - K(Xq, X) (K + C_hat^{-1})^{-1} K(X, Xq)``.

The ``p x p`` matrix ``A = (K + C_hat^{-1})^{-1}`` is formed once per fit by Woodbury without
inverting ``K`` or ``C_hat`` (``C_hat`` may be singular):
``A = C_hat - C_hat L B^{-1} L^T C_hat`` with ``K = L L^T`` and ``B = I + L^T C_hat L``
(the surrogate's ``chol_K`` and ``chol_B``), so every t-batch costs two small matrix
products. This is the quantity of :meth:`PairwiseGPSurrogate.posterior_mean_cov`, tested
against it batch by batch. Differentiable in ``X``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import torch
from botorch.acquisition.objective import PosteriorTransform
from botorch.models.model import Model
from botorch.posteriors.gpytorch import GPyTorchPosterior
from gpytorch.distributions import MultivariateNormal
from linear_operator import to_linear_operator
from torch import Tensor

from localpbo_core.surrogate import Surrogate
from localpbo_core.surrogate.kernel import se_kernel, se_kernel_exact


@dataclass(frozen=True)
class PosteriorCache:
    """Per-fit constants of the joint posterior: ``alpha = K^{-1} f_hat`` ``(p,)`` and
    ``A = (K + C_hat^{-1})^{-1}`` ``(p, p)`` (paper Sec. 4)."""

    train_inputs: Tensor
    lengthscale: Tensor
    outputscale: float
    alpha: Tensor
    A: Tensor

    @classmethod
    def from_surrogate(cls, surrogate: Surrogate) -> PosteriorCache:
        """Form ``alpha`` and ``A`` (Woodbury, see the module docstring)."""
        L, LB = surrogate.chol_K, surrogate.chol_B
        p = L.shape[0]
        C = surrogate.likelihood_hessian
        if surrogate.eps_reg > 0:
            C = C + surrogate.eps_reg * torch.eye(p, dtype=C.dtype)
        G = C @ L  # C_hat L
        A = C - G @ torch.cholesky_solve(G.transpose(0, 1), LB)
        A = 0.5 * (A + A.transpose(0, 1))
        alpha = torch.cholesky_solve(surrogate.utility.reshape(p, 1), L).reshape(p)
        ls = torch.as_tensor(surrogate.lengthscale, dtype=torch.float64)
        return cls(surrogate.train_inputs, ls, float(surrogate.outputscale), alpha, A)


def batched_mean_cov(surrogate: Surrogate | PosteriorCache, X: Tensor) -> tuple[Tensor, Tensor]:
    """Joint posterior of ``f`` per t-batch (paper Sec. 4, eq. (11) "general covariance block").

    Args:
        surrogate: a fitted surrogate or its :class:`PosteriorCache`.
        X: ``(B, q, d)`` float64 points.

    Returns:
        mean ``(B, q)`` and covariance ``(B, q, q)``; batch ``b`` equals
        ``surrogate.posterior_mean_cov(X[b])``.
    """
    cache = (
        surrogate
        if isinstance(surrogate, PosteriorCache)
        else PosteriorCache.from_surrogate(surrogate)
    )
    d = cache.train_inputs.shape[1]
    if X.ndim != 3 or X.shape[-1] != d:
        raise ValueError(f"X: expected shape (B, q, {d}), got {tuple(X.shape)}")
    if X.dtype != torch.float64:
        raise ValueError(f"X: expected dtype torch.float64, got {X.dtype}")
    k = se_kernel(X, cache.train_inputs, cache.lengthscale, cache.outputscale)  # (B, q, p)
    mean = k @ cache.alpha
    prior = se_kernel_exact(X, X, cache.lengthscale, cache.outputscale)  # (B, q, q)
    cov = prior - (k @ cache.A) @ k.transpose(-1, -2)
    return mean, 0.5 * (cov + cov.transpose(-1, -2))


class SurrogateModel(Model):
    """BoTorch ``Model`` whose ``posterior`` is the surrogate's joint Laplace posterior.

    ``datapoints`` (the unique training inputs) is exposed because BoTorch's analytic EUBO
    reads its dtype and device from ``pref_model.datapoints``.
    """

    def __init__(self, surrogate: Surrogate) -> None:
        super().__init__()
        self.surrogate = surrogate
        self.cache = PosteriorCache.from_surrogate(surrogate)
        self.datapoints = surrogate.train_inputs

    @property
    def num_outputs(self) -> int:
        """One latent utility."""
        return 1

    @property
    def batch_shape(self) -> torch.Size:
        """No model batch (a single GP)."""
        return torch.Size([])

    def posterior(
        self,
        X: Tensor,
        output_indices: list[int] | None = None,
        observation_noise: bool | Tensor = False,
        posterior_transform: PosteriorTransform | None = None,
        **kwargs: Any,
    ) -> GPyTorchPosterior:
        """Joint posterior over the ``q`` points of every t-batch of ``X`` (``... x q x d``).

        Observation noise is not applicable (preferences, probit noise is in the likelihood).
        """
        if observation_noise is not False:
            raise ValueError("observation_noise: not supported by the preference surrogate")
        if output_indices not in (None, [0]):
            raise ValueError(f"output_indices: the model has one output, got {output_indices}")
        if X.ndim < 2:
            raise ValueError(f"X: expected shape (..., q, d), got {tuple(X.shape)}")
        batch, (q, d) = X.shape[:-2], X.shape[-2:]
        mean, cov = batched_mean_cov(self.cache, X.reshape(-1, q, d))
        # A linear operator defers the Cholesky to gpytorch's psd_safe_cholesky, which adds
        # jitter only when needed (e.g. two coincident points of a q-batch at a bound).
        mvn = MultivariateNormal(
            mean.reshape(*batch, q), to_linear_operator(cov.reshape(*batch, q, q))
        )
        post = GPyTorchPosterior(mvn)
        if posterior_transform is not None:
            return posterior_transform(post)
        return post
