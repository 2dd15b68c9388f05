"""Posterior mean gradient/Hessian (paper Sec. 4, mu_grad, mu_hess) vs autograd and finite
differences of the posterior mean."""

from __future__ import annotations

import pytest
import torch

from localpbo_core.surrogate import PairwiseGPSurrogate


def _fit(duels, d: int, seed: int) -> PairwiseGPSurrogate:
    X, comp = duels(d, 4 * d + 6, seed)
    g = torch.Generator().manual_seed(100 + seed)
    ls = 0.15 + 0.35 * torch.rand(d, generator=g, dtype=torch.float64)
    return PairwiseGPSurrogate.fit(X, comp, lengthscale=ls, outputscale=2.5)


@pytest.mark.parametrize("d", [1, 3, 6, 12])
def test_gradient_and_hessian_match_autograd(duels, d):
    s = _fit(duels, d, seed=d)
    g = torch.Generator().manual_seed(7 * d)
    for x in torch.rand(4, d, generator=g, dtype=torch.float64):
        grad_ad = torch.func.grad(s.mean)(x)
        hess_ad = torch.func.hessian(s.mean)(x)
        torch.testing.assert_close(s.mean_gradient(x), grad_ad, rtol=1e-10, atol=1e-12)
        torch.testing.assert_close(s.mean_hessian(x), hess_ad, rtol=1e-10, atol=1e-12)


@pytest.mark.parametrize("d", [1, 3, 6, 12])
def test_gradient_and_hessian_match_finite_differences(duels, d):
    s = _fit(duels, d, seed=d)
    g = torch.Generator().manual_seed(11 * d)
    h = 1e-5
    eye = torch.eye(d, dtype=torch.float64)
    for x in 0.1 + 0.8 * torch.rand(3, d, generator=g, dtype=torch.float64):
        # central differences: truncation O(h^2 * |f'''|), rounding O(eps |f| / h)
        fd_grad = torch.stack([(s.mean(x + h * e) - s.mean(x - h * e)) / (2 * h) for e in eye])
        fd_hess = torch.stack(
            [(s.mean_gradient(x + h * e) - s.mean_gradient(x - h * e)) / (2 * h) for e in eye]
        )
        scale_g = 1.0 + s.mean_gradient(x).abs().max()
        scale_h = 1.0 + s.mean_hessian(x).abs().max()
        torch.testing.assert_close(s.mean_gradient(x), fd_grad, rtol=0, atol=1e-7 * scale_g)
        torch.testing.assert_close(s.mean_hessian(x), fd_hess, rtol=0, atol=1e-6 * scale_h)


def test_batch_shapes_agree_with_single_points(duels):
    s = _fit(duels, 4, seed=3)
    xs = torch.rand(5, 4, generator=torch.Generator().manual_seed(1), dtype=torch.float64)
    torch.testing.assert_close(s.mean(xs), torch.stack([s.mean(x) for x in xs]))
    torch.testing.assert_close(s.mean_gradient(xs), torch.stack([s.mean_gradient(x) for x in xs]))
    torch.testing.assert_close(s.mean_hessian(xs), torch.stack([s.mean_hessian(x) for x in xs]))
    torch.testing.assert_close(s.variance(xs), torch.stack([s.variance(x) for x in xs]))
    torch.testing.assert_close(
        s.gradient_covariance(xs), torch.stack([s.gradient_covariance(x) for x in xs])
    )
    assert s.mean(xs[0]).shape == ()
    assert s.mean_gradient(xs[0]).shape == (4,)
    assert s.mean_hessian(xs[0]).shape == (4, 4)
