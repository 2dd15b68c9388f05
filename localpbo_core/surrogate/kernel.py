"""Scaled ARD squared-exponential kernel and its derivatives.

The prior of the pairwise GP (paper Sec. 4, "Prior"; the shared pairwise-GP settings of
App. D.2) is ``ScaleKernel(RBFKernel(ard))``:

    k(x, x') = s * exp(-0.5 * sum_i (x_i - x'_i)^2 / l_i^2).

The derivative kernels ``k_a(x, X) = L_{a,x} K(x, X)`` of paper eq. (11) "general covariance
block" and the prior blocks ``L_{a,x} L_{b,x'} k(x, x')|_{x'=x}`` are given in closed form here.
With ``Lambda = diag(1 / l^2)`` and ``r_j = Lambda (x - X_j)``:

    k_0(x, X_j) = k(x, X_j)
    k_1(x, X_j) = -k(x, X_j) r_j                              (d,)
    k_2(x, X_j) = k(x, X_j) (r_j r_j^T - Lambda)              (d, d)

and by the symmetry of a stationary kernel ``k_b(X, x) = k_b(x, X)^T`` (derivatives w.r.t. the
second argument).
"""

from __future__ import annotations

import torch
from torch import Tensor


def se_kernel(x1: Tensor, x2: Tensor, lengthscale: Tensor, outputscale: Tensor | float) -> Tensor:
    """Cross-covariance matrix ``k(x1_i, x2_j)`` of shape ``(n1, n2)`` (paper Sec. 4, "Prior")."""
    a = x1 / lengthscale
    b = x2 / lengthscale
    sq = (a * a).sum(-1, keepdim=True) - 2.0 * a @ b.transpose(-1, -2) + (b * b).sum(-1)
    return outputscale * torch.exp(-0.5 * sq.clamp_min(0.0))


def se_kernel_exact(
    x1: Tensor, x2: Tensor, lengthscale: Tensor, outputscale: Tensor | float
) -> Tensor:
    """Like :func:`se_kernel` but from explicit differences (exact near the diagonal, and smooth
    for autograd at coincident points). Shape ``(..., n1, n2)``."""
    diff = (x1.unsqueeze(-2) - x2.unsqueeze(-3)) / lengthscale
    return outputscale * torch.exp(-0.5 * (diff * diff).sum(-1))


def kernel_derivatives(
    x: Tensor, X: Tensor, lengthscale: Tensor, outputscale: Tensor | float, order: int
) -> tuple[Tensor, ...]:
    """Derivative kernels ``k_0, k_1, k_2`` of eq. (11) "general covariance block" up to ``order``.

    Args:
        x: query points ``(N, d)``.
        X: training points ``(p, d)``.
    Returns:
        ``(k0,)``, ``(k0, k1)`` or ``(k0, k1, k2)`` with shapes ``(N, p)``, ``(N, p, d)``,
        ``(N, p, d, d)``.
    """
    inv_l2 = lengthscale.pow(-2)
    diff = x.unsqueeze(-2) - X  # (N, p, d)
    r = diff * inv_l2
    k0 = outputscale * torch.exp(-0.5 * (diff * r).sum(-1))
    if order == 0:
        return (k0,)
    k1 = -k0.unsqueeze(-1) * r
    if order == 1:
        return (k0, k1)
    k2 = k0[..., None, None] * (r.unsqueeze(-1) * r.unsqueeze(-2) - torch.diag(inv_l2))
    return (k0, k1, k2)


def prior_block(a: int, b: int, lengthscale: Tensor, outputscale: Tensor | float) -> Tensor:
    """Prior block ``L_{a,x} L_{b,x'} k(x, x')|_{x'=x}`` of eq. (11) "general covariance block".

    Stationarity gives (``Lambda = diag(1/l^2)``, Hessians vectorised row-major, ``D = d^2``):
    ``00 = s``, ``01 = 0``, ``02 = -s vec(Lambda)``, ``11 = s Lambda``, ``12 = 0``,
    ``22[ij,kl] = s (L_ij L_kl + L_ik L_jl + L_il L_jk)`` (fourth derivative of the Gaussian).
    Always returned as a matrix of shape ``(n_a, n_b)`` with ``n_0 = 1, n_1 = d, n_2 = d^2``;
    ``ba`` is the transpose of ``ab``.
    """
    if a not in (0, 1, 2) or b not in (0, 1, 2):
        raise ValueError(f"derivative orders must be in {{0, 1, 2}}, got ({a}, {b})")
    if a > b:
        return prior_block(b, a, lengthscale, outputscale).transpose(-1, -2)
    d = lengthscale.shape[-1]
    dt = lengthscale.dtype
    lam = torch.diag(lengthscale.pow(-2))
    s = torch.as_tensor(outputscale, dtype=dt)
    if (a, b) == (0, 0):
        return s.reshape(1, 1).clone()
    if (a, b) == (0, 1):
        return torch.zeros(1, d, dtype=dt)
    if (a, b) == (0, 2):
        return -s * lam.reshape(1, -1)
    if (a, b) == (1, 1):
        return s * lam
    if (a, b) == (1, 2):
        return torch.zeros(d, d * d, dtype=dt)
    t = (
        torch.einsum("ij,kl->ijkl", lam, lam)
        + torch.einsum("ik,jl->ijkl", lam, lam)
        + torch.einsum("il,jk->ijkl", lam, lam)
    )
    return s * t.reshape(d * d, d * d)
