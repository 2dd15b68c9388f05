"""Covariance blocks of eq. (11) "general covariance block" vs independent computations: gpytorch's
``RBFKernelGrad`` joint prior of [f, grad f] with the Laplace formula and a dense inverse, and
autograd of the kernel for the Hessian blocks."""

from __future__ import annotations

import pytest
import torch
from gpytorch.kernels import RBFKernelGrad

from localpbo_core.surrogate import PairwiseGPSurrogate
from localpbo_core.surrogate.kernel import se_kernel_exact
from localpbo_core.surrogate.laplace import likelihood_hessian, probit_terms


def _fit(duels, d, seed, eps_reg):
    X, comp = duels(d, 5 * d + 5, seed)
    ls = torch.linspace(0.15, 0.4, d, dtype=torch.float64)
    return PairwiseGPSurrogate.fit(X, comp, lengthscale=ls, outputscale=1.7, eps_reg=eps_reg)


def _dense_c_hat(s):
    p = s.train_inputs.shape[0]
    t = probit_terms(s.utility, s.winners, s.losers, None)
    C = likelihood_hessian(t, s.winners, s.losers, p)
    return C + s.eps_reg * torch.eye(p, dtype=torch.float64)


@pytest.mark.parametrize("d", [1, 3, 6])
def test_blocks_00_01_11_match_rbfkernelgrad(duels, d):
    s = _fit(duels, d, seed=20 + d, eps_reg=1e-4)
    X = s.train_inputs
    p = X.shape[0]
    kern = RBFKernelGrad(ard_num_dims=d).to(torch.float64)
    kern.lengthscale = s.lengthscale.reshape(1, d)
    x = torch.rand(1, d, generator=torch.Generator().manual_seed(d), dtype=torch.float64)
    with torch.no_grad():
        full = s.outputscale * kern(torch.cat([X, x]), torch.cat([X, x])).to_dense()
    # RBFKernelGrad orders rows as [f(z_1), grad f(z_1), f(z_2), ...]: pick f at X, then
    # [f, grad f] at x.
    blk = d + 1
    idx_fX = torch.arange(p) * blk
    idx_x = p * blk + torch.arange(blk)
    K = full[idx_fX][:, idx_fX]
    kx = full[idx_x][:, idx_fX]  # (1 + d, p): [k_0; k_1] at x
    prior = full[idx_x][:, idx_x]
    c_hat = _dense_c_hat(s)
    K = K + s.jitter * s.outputscale * torch.eye(p, dtype=torch.float64)
    post = prior - kx @ torch.linalg.inv(K + torch.linalg.inv(c_hat)) @ kx.T
    blocks = s.covariance_blocks(x[0], orders=(0, 1))
    # the dense inverse of C_hat (condition ~1/eps_reg) limits the reference's precision
    tol = dict(rtol=1e-6, atol=1e-8 * s.outputscale)
    torch.testing.assert_close(blocks["00"], post[0, 0], **tol)
    torch.testing.assert_close(blocks["01"], post[0, 1:], **tol)
    torch.testing.assert_close(blocks["11"], post[1:, 1:], **tol)
    torch.testing.assert_close(s.gradient_covariance(x[0]), post[1:, 1:], **tol)
    torch.testing.assert_close(s.variance(x[0]), post[0, 0], **tol)


def _autograd_blocks(s, x):
    """[f, grad f, vec hess f] prior blocks by autograd of the kernel, then eq.
    (general_covariance_block) with (K^{-1} + C_hat)^{-1} by a dense inverse (eps_reg = 0)."""
    X = s.train_inputs
    p, d = X.shape

    def k(a, b):
        return se_kernel_exact(a[None], b[None], s.lengthscale, s.outputscale)[0, 0]

    def ops(fun_of_x, x0):
        return [
            fun_of_x(x0).reshape(1),
            torch.func.jacrev(fun_of_x)(x0).reshape(d),
            torch.func.hessian(fun_of_x)(x0).reshape(d * d),
        ]

    kX = [
        torch.stack(c, dim=-1)
        for c in zip(*[ops(lambda z, xj=xj: k(z, xj), x) for xj in X], strict=True)
    ]
    kX = [v.T for v in kX]  # each (p, n_a)

    def prior_row(a):
        def g(z):
            return ops(lambda zz: k(zz, z), x)[a]

        return g

    prior = {}
    for a in range(3):
        for b in range(3):
            fa = prior_row(a)
            if b == 0:
                prior[a, b] = fa(x).reshape(-1, 1)
            elif b == 1:
                prior[a, b] = torch.func.jacrev(fa)(x)
            else:
                prior[a, b] = torch.func.jacrev(torch.func.jacrev(fa))(x).reshape(-1, d * d)
    K = se_kernel_exact(X, X, s.lengthscale, s.outputscale)
    K = K + s.jitter * s.outputscale * torch.eye(p, dtype=torch.float64)
    Kinv = torch.linalg.inv(K)
    A = Kinv - Kinv @ torch.linalg.inv(Kinv + _dense_c_hat(s)) @ Kinv
    return {f"{a}{b}": prior[a, b] - kX[a].T @ A @ kX[b] for a in range(3) for b in range(a, 3)}


@pytest.mark.parametrize("d", [1, 2, 3])
def test_all_blocks_match_autograd_of_kernel(duels, d):
    s = _fit(duels, d, seed=40 + d, eps_reg=0.0)
    x = torch.rand(d, generator=torch.Generator().manual_seed(3 + d), dtype=torch.float64)
    ref = _autograd_blocks(s, x)
    ours = s.covariance_blocks(x)
    # The dense-inverse reference loses about cond(K) * eps (cond(K) ~ 1e8 for 11 random points
    # in 1-D); the tolerance follows it, floored at 1e-9 relative.
    K = s.chol_K @ s.chol_K.T
    rel = max(1e-9, 100 * torch.finfo(torch.float64).eps * float(torch.linalg.cond(K)))
    for key, value in ref.items():
        expected = value.reshape(ours[key].shape)
        scale = 1.0 + expected.abs().max()
        torch.testing.assert_close(ours[key], expected, rtol=0, atol=rel * scale, msg=key)


def test_posterior_mean_cov_matches_blocks_and_is_differentiable(duels):
    s = _fit(duels, 3, seed=5, eps_reg=0.0)
    Xq = torch.rand(4, 3, generator=torch.Generator().manual_seed(9), dtype=torch.float64)
    mean, cov = s.posterior_mean_cov(Xq)
    torch.testing.assert_close(mean, s.mean(Xq))
    torch.testing.assert_close(torch.diagonal(cov), s.variance(Xq))
    # d cov_00(x, x) / dx equals 2 Sigma_01(x) (symmetry of the posterior covariance)
    x = Xq[0].clone().requires_grad_(True)
    var = s.posterior_mean_cov(x[None])[1][0, 0]
    (grad,) = torch.autograd.grad(var, x)
    torch.testing.assert_close(grad, 2.0 * s.covariance_blocks(Xq[0], (0, 1))["01"])


def test_eps_reg_override_matches_refit(duels):
    X, comp = duels(3, 20, seed=8)
    base = PairwiseGPSurrogate.fit(X, comp, lengthscale=0.3, outputscale=1.5)
    reg = PairwiseGPSurrogate.fit(X, comp, lengthscale=0.3, outputscale=1.5, eps_reg=1e-2)
    x = torch.rand(3, generator=torch.Generator().manual_seed(2), dtype=torch.float64)
    torch.testing.assert_close(
        base.gradient_covariance(x, eps_reg=1e-2), reg.gradient_covariance(x)
    )
    torch.testing.assert_close(
        base.gradient_covariance(x, eps_reg=0.0), base.gradient_covariance(x)
    )
    # more likelihood precision can only shrink the posterior covariance
    diff = base.gradient_covariance(x) - reg.gradient_covariance(x)
    assert torch.linalg.eigvalsh(diff).min() > -1e-12
