"""Posterior sample paths of the Laplace-approximated pairwise GP (paper Sec. 4; used by TuRPBO
for Thompson sampling, paper Sec. 5.3 "TuRPBO" and App. C.5, and by PrefSQP's line search).

Pathwise (Matheron) conditioning: with a prior path ``g`` and a draw ``f_X`` of the Laplace
posterior ``q(f_X) = N(f_hat, (K^{-1} + C_hat)^{-1})`` at the training points,

    path(x) = g(x) + k(x, X) K^{-1} (f_X - g(X))

has exactly the Laplace predictive mean ``k(x, X) K^{-1} f_hat`` and covariance
``k(x, x') - k(x, X) (K + C_hat^{-1})^{-1} k(X, x')`` of eq. (11) "general covariance block" when
``g`` is an exact prior draw. ``g`` uses random Fourier features of the SE-ARD kernel,
``g(x) = sqrt(2 s / F) sum_f w_f cos(omega_f^T x + b_f)``, ``omega_f ~ N(0, diag(1/l^2))``,
``b_f ~ U(0, 2 pi)``, ``w_f ~ N(0, 1)``; every path draws its own frequencies, so the prior
covariance is exact in distribution (not only as ``F -> inf``).
``f_X = f_hat + L L_B^{-T} xi`` with ``K = L L^T``, ``I + L^T C_hat L = L_B L_B^T``,
``xi ~ N(0, I)``, since ``(K^{-1} + C_hat)^{-1} = L B^{-1} L^T``.

Closed-form gradient (used by the Thompson-sampling optimiser instead of autograd): with
``u = K^{-1} (f_X - g(X))`` and ``Lambda = diag(1 / l^2)``,

    grad g(x)    = -sqrt(2 s / F) sum_f w_f sin(omega_f^T x + b_f) omega_f
    grad k(x, X) u = -Lambda sum_j u_j k(x, X_j) (x - X_j)
                   = -Lambda (x (k(x, X) u) - k(x, X) (u * X))

(the first-derivative kernel ``k_1`` of :mod:`.kernel`).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np
import torch
from torch import Tensor

from .kernel import se_kernel

if TYPE_CHECKING:
    from .protocol import Surrogate


class SamplePaths:
    """``P`` posterior sample paths of one surrogate (see the module docstring).

    Calling ``paths(x)`` with a float64 tensor ``(N, d)`` returns ``(N, P)`` values and is
    differentiable by torch autograd. :meth:`value_and_grad` evaluates values and the analytic
    gradient in float64 numpy without autograd (the fast route of the Thompson optimiser); the
    matrix products run in numpy (BLAS), the cosines in torch on the same memory (its
    vectorised ``cos``/``sin`` are several times faster than numpy's in float64).

    Attributes:
        num_paths: ``P``.
        dim: ``d``.
    """

    def __init__(
        self,
        train_inputs: Tensor,
        lengthscale: Tensor,
        outputscale: float,
        omega: Tensor,
        phase: Tensor,
        weights: Tensor,
        amp: float,
        update: Tensor,
    ) -> None:
        self._X = train_inputs
        self._ls = lengthscale
        self._os = float(outputscale)
        self._omega = omega  # (P, F, d)
        self._phase = phase  # (P, F)
        self._weights = weights  # (P, F)
        self._amp = float(amp)
        self._update = update  # (P_train, P)
        self.num_paths = int(omega.shape[0])
        self.dim = int(train_inputs.shape[1])
        # float64 numpy copies for the analytic route; per path j (x_aug = [x, 1]):
        #   prior value  = cos(x_aug W_j) @ (amp w_j),  W_j = [omega_j^T; b_j]  (d + 1, F)
        #   prior grad   = -sin(x_aug W_j) @ (amp w_j[:, None] omega_j)
        #   kernel value = k(x, X) @ u_j,  kernel grad = -Lambda (x (k u_j) - k @ (u_j * X))
        ls = lengthscale.detach().numpy().astype(np.float64)
        X = train_inputs.detach().numpy().astype(np.float64)
        u = update.numpy()  # (p, P)
        self._np_w_aug, self._np_aw = _rff_numpy(omega, phase, weights, amp)
        self._np_awom = self._np_aw[:, :, None] * omega.numpy()  # (P, F, d)
        self._np_inv_l = 1.0 / ls
        self._np_inv_l2 = self._np_inv_l**2
        # log k(x, X_j) = [a, -|a|^2 / 2, 1] . [b_j, 1, log s - |b_j|^2 / 2], a = x / l, b = X / l
        b = X * self._np_inv_l
        self._np_log_s = math.log(self._os)
        self._np_b_aug = np.concatenate(
            [b.T, np.ones((1, b.shape[0])), self._np_log_s - 0.5 * (b * b).sum(-1)[None, :]]
        )  # (d + 2, p)
        # columns [u_j, u_j * X] so that one matmul k @ _np_uux[j] gives (k u_j, k (u_j X))
        self._np_uux = np.concatenate(
            [u.T[:, :, None], u.T[:, :, None] * X[None, :, :]], axis=2
        )  # (P, p, 1 + d)

    # ------------------------------------------------------------------ torch (autograd)
    def _prior(self, x: Tensor) -> Tensor:
        feats = self._amp * torch.cos(torch.einsum("nd,sfd->nsf", x, self._omega) + self._phase)
        return (feats * self._weights).sum(-1)  # (N, P)

    def __call__(self, x: Tensor) -> Tensor:
        """Path values ``(N, P)`` at float64 ``x (N, d)``; differentiable by autograd."""
        if not isinstance(x, Tensor) or x.ndim != 2 or x.shape[1] != self.dim:
            raise ValueError(f"x must be a float64 tensor of shape (N, {self.dim})")
        if x.dtype != torch.float64:
            raise ValueError(f"x must be a float64 tensor of shape (N, {self.dim})")
        return self._prior(x) + se_kernel(x, self._X, self._ls, self._os) @ self._update

    # ------------------------------------------------------------------ numpy (analytic)
    def _check_np(self, x: np.ndarray) -> np.ndarray:
        if not isinstance(x, np.ndarray) or x.ndim != 2 or x.shape[1] != self.dim:
            raise ValueError(f"x must be a numpy array of shape (N, {self.dim})")
        if x.dtype != np.float64:
            raise ValueError(f"x must have dtype float64, got {x.dtype}")
        return x

    def _kernel(self, x: np.ndarray) -> np.ndarray:
        """``k(x, X)`` ``(N, p)`` (paper Sec. 4 prior) as ``exp`` of one augmented product;
        ``min(., log s)`` is the ``max(sq, 0)`` clamp of :func:`se_kernel`."""
        a = x * self._np_inv_l
        a_aug = np.empty((x.shape[0], self.dim + 2))
        a_aug[:, : self.dim] = a
        a_aug[:, self.dim] = -0.5 * (a * a).sum(-1)
        a_aug[:, self.dim + 1] = 1.0
        log_k = a_aug @ self._np_b_aug
        np.minimum(log_k, self._np_log_s, out=log_k)
        return np.exp(log_k, out=log_k)

    def value_and_grad(
        self, x: np.ndarray, index: int | None = None
    ) -> tuple[np.ndarray, np.ndarray]:
        """Path values and analytic input gradients (module docstring), no autograd.

        Args:
            x: ``(N, d)`` float64 numpy points.
            index: one path ``j`` (only that path is computed) or None for all.

        Returns:
            ``index`` None: values ``(N, P)`` and gradients ``(N, P, d)``;
            ``index`` j: values ``(N,)`` and gradients ``(N, d)`` of path j.
        """
        x = self._check_np(x)
        if index is None:
            outs = [self.value_and_grad(x, j) for j in range(self.num_paths)]
            return np.stack([v for v, _ in outs], 1), np.stack([g for _, g in outs], 1)
        j = int(index)
        if not 0 <= j < self.num_paths:
            raise ValueError(f"index must be in [0, {self.num_paths}), got {index}")
        z = _augment(x) @ self._np_w_aug[j]
        zt = torch.from_numpy(z)
        sin = torch.sin(zt).numpy()
        cos = zt.cos_().numpy()  # in place: z now holds cos(z)
        kuux = self._kernel(x) @ self._np_uux[j]  # (N, 1 + d)
        val = cos @ self._np_aw[j] + kuux[:, 0]
        grad = -(sin @ self._np_awom[j])
        grad -= self._np_inv_l2 * (x * kuux[:, :1] - kuux[:, 1:])
        return val, grad

    def values(self, x: np.ndarray, index: int | None = None) -> np.ndarray:
        """Path values only, float64 numpy: ``(N, P)``, or ``(N,)`` for path ``index``."""
        x = self._check_np(x)
        if index is None:
            return np.stack([self.values(x, j) for j in range(self.num_paths)], 1)
        j = int(index)
        if not 0 <= j < self.num_paths:
            raise ValueError(f"index must be in [0, {self.num_paths}), got {index}")
        prior = _rff_values(_augment(x), self._np_w_aug[j], self._np_aw[j])
        return prior + self._kernel(x) @ self._np_uux[j][:, 0]


def _augment(x: np.ndarray) -> np.ndarray:
    """``[x, 1]`` ``(N, d + 1)``: the RFF phase then enters the same matrix product."""
    out = np.empty((x.shape[0], x.shape[1] + 1))
    out[:, :-1] = x
    out[:, -1] = 1.0
    return out


def _rff_numpy(
    omega: Tensor, phase: Tensor, weights: Tensor, amp: float
) -> tuple[np.ndarray, np.ndarray]:
    """Per path ``W_j = [omega_j^T; b_j]`` ``(P, d + 1, F)`` and ``amp w_j`` ``(P, F)``."""
    w_aug = np.concatenate([omega.numpy().transpose(0, 2, 1), phase.numpy()[:, None, :]], axis=1)
    return np.ascontiguousarray(w_aug), amp * weights.numpy()


def _rff_values(x_aug: np.ndarray, w_aug: np.ndarray, aw: np.ndarray) -> np.ndarray:
    """RFF prior path ``g(x) = sum_f amp w_f cos(omega_f^T x + b_f)`` (module docstring) of
    one path at ``x_aug = [x, 1]``; the cosine runs in torch, in place on the product."""
    z = x_aug @ w_aug
    return torch.from_numpy(z).cos_().numpy() @ aw


def path_draws(
    surrogate: Surrogate, num_paths: int, generator: torch.Generator, num_features: int
) -> tuple[Tensor, Tensor, Tensor, Tensor, float]:
    """The random draws of ``P = num_paths`` paths of ``F = num_features`` random Fourier
    features each (module docstring), in the order they are taken from ``generator``: the
    frequencies ``omega`` ``(P, F, d)`` (already divided by the lengthscales), the phases ``b``
    ``(P, F)``, the weights ``w`` ``(P, F)``, the standard normal ``xi`` ``(p, P)`` of ``f_X``,
    and the amplitude ``sqrt(2 s / F)``."""
    dt = torch.float64
    p, d = surrogate.train_inputs.shape
    S, F = int(num_paths), int(num_features)
    omega = torch.randn(S, F, d, generator=generator, dtype=dt) / surrogate.lengthscale.detach()
    phase = 2.0 * math.pi * torch.rand(S, F, generator=generator, dtype=dt)
    weights = torch.randn(S, F, generator=generator, dtype=dt)
    xi = torch.randn(p, S, generator=generator, dtype=dt)
    amp = math.sqrt(2.0 * float(surrogate.outputscale) / F)
    return omega, phase, weights, xi, amp


def draw_sample_paths(
    surrogate: Surrogate,
    num_paths: int,
    generator: torch.Generator,
    num_features: int = 1024,
) -> SamplePaths:
    """Draw ``num_paths`` posterior paths; the result maps ``x (N, d) -> values (N, num_paths)``
    and offers :meth:`SamplePaths.value_and_grad`."""
    if not isinstance(generator, torch.Generator):
        raise ValueError("generator must be a torch.Generator")
    if num_paths < 1 or num_features < 1:
        raise ValueError("num_paths and num_features must be >= 1")
    X = surrogate.train_inputs.detach()
    ls = surrogate.lengthscale.detach()
    os_ = float(surrogate.outputscale)
    S = int(num_paths)
    omega, phase, weights, xi, amp = path_draws(surrogate, num_paths, generator, num_features)

    L = surrogate.chol_K
    LB = surrogate.chol_B
    with torch.no_grad():
        noise = torch.linalg.solve_triangular(LB.transpose(0, 1), xi, upper=True)
        f_samples = surrogate.utility.unsqueeze(-1) + L @ noise  # (p, S)
        w_aug, aw = _rff_numpy(omega, phase, weights, amp)
        X_aug = _augment(X.numpy().astype(np.float64))
        prior_X = np.stack([_rff_values(X_aug, w_aug[j], aw[j]) for j in range(S)], 1)
        resid = f_samples - torch.from_numpy(prior_X)
        update = torch.cholesky_solve(resid, L)  # K^{-1} (f_X - g(X)), (p, S)
    return SamplePaths(X, ls, os_, omega, phase, weights, amp, update)
