"""Posterior sample paths of the Laplace-approximated pairwise GP (paper Sec. 4; used by TuRPBO
for Thompson sampling, paper Sec. TuRPBO / App. D).

Pathwise (Matheron) conditioning: with a prior path ``g`` and a draw ``f_X`` of the Laplace
posterior ``q(f_X) = N(f_hat, (K^{-1} + C_hat)^{-1})`` at the training points,

    path(x) = g(x) + k(x, X) K^{-1} (f_X - g(X))

has exactly the Laplace predictive mean ``k(x, X) K^{-1} f_hat`` and covariance
``k(x, x') - k(x, X) (K + C_hat^{-1})^{-1} k(X, x')`` of eq. (general_covariance_block) when
``g`` is an exact prior draw. ``g`` uses random Fourier features of the SE-ARD kernel,
``g(x) = sqrt(2 s / F) sum_f w_f cos(omega_f^T x + b_f)``, ``omega_f ~ N(0, diag(1/l^2))``,
``b_f ~ U(0, 2 pi)``, ``w_f ~ N(0, 1)``; every path draws its own frequencies, so the prior
covariance is exact in distribution (not only as ``F -> inf``).
``f_X = f_hat + L L_B^{-T} xi`` with ``K = L L^T``, ``I + L^T C_hat L = L_B L_B^T``,
``xi ~ N(0, I)``, since ``(K^{-1} + C_hat)^{-1} = L B^{-1} L^T``.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import TYPE_CHECKING

import torch
from torch import Tensor

from .kernel import se_kernel

if TYPE_CHECKING:
    from .pairwise_gp import PairwiseGPSurrogate


def draw_sample_paths(
    surrogate: PairwiseGPSurrogate,
    num_paths: int,
    generator: torch.Generator,
    num_features: int = 1024,
) -> Callable[[Tensor], Tensor]:
    """Draw ``num_paths`` posterior paths; returns ``x (N, d) -> values (N, num_paths)``."""
    if not isinstance(generator, torch.Generator):
        raise ValueError("generator must be a torch.Generator")
    if num_paths < 1 or num_features < 1:
        raise ValueError("num_paths and num_features must be >= 1")
    dt = torch.float64
    X = surrogate.train_inputs
    p, d = X.shape
    ls = surrogate.lengthscale
    os_ = surrogate.outputscale
    S, F = int(num_paths), int(num_features)
    omega = torch.randn(S, F, d, generator=generator, dtype=dt) / ls
    phase = 2.0 * math.pi * torch.rand(S, F, generator=generator, dtype=dt)
    weights = torch.randn(S, F, generator=generator, dtype=dt)
    xi = torch.randn(p, S, generator=generator, dtype=dt)
    amp = math.sqrt(2.0 * os_ / F)

    def prior(x: Tensor) -> Tensor:
        feats = amp * torch.cos(torch.einsum("nd,sfd->nsf", x, omega) + phase)
        return (feats * weights).sum(-1)  # (N, S)

    L = surrogate.chol_K
    LB = surrogate.chol_B
    with torch.no_grad():
        noise = torch.linalg.solve_triangular(LB.transpose(0, 1), xi, upper=True)
        f_samples = surrogate.utility.unsqueeze(-1) + L @ noise  # (p, S)
        resid = f_samples - prior(X)
        update = torch.cholesky_solve(resid, L)  # K^{-1} (f_X - g(X)), (p, S)

    def path(x: Tensor) -> Tensor:
        if not isinstance(x, Tensor) or x.ndim != 2 or x.shape[1] != d or x.dtype != dt:
            raise ValueError(f"x must be a float64 tensor of shape (N, {d})")
        return prior(x) + se_kernel(x, X, ls, os_) @ update

    return path
