"""Posterior sample paths (pathwise conditioning on the Laplace posterior) vs the joint
Laplace posterior ``posterior_mean_cov`` (paper Sec. 4)."""

from __future__ import annotations

import torch

from localpbo_core.surrogate import PairwiseGPSurrogate


def test_path_moments_match_posterior(duels):
    d = 3
    X, comp = duels(d, 15, seed=4)
    s = PairwiseGPSurrogate.fit(X, comp, lengthscale=0.3, outputscale=2.0)
    g = torch.Generator().manual_seed(0)
    Xq = torch.cat([torch.rand(3, d, generator=g, dtype=torch.float64), X[:1]])
    n_paths = 10000
    paths = s.sample_paths(n_paths, torch.Generator().manual_seed(1), num_features=32)
    vals = paths(Xq)  # (4, n_paths)
    assert vals.shape == (4, n_paths)
    mean, cov = s.posterior_mean_cov(Xq)
    emp_mean = vals.mean(1)
    emp_cov = torch.cov(vals)
    sd = torch.diagonal(cov).sqrt()
    # Every path draws its own frequencies, so even 32 features give exact prior moments.
    # Monte Carlo: std error of the mean is sd / sqrt(n) (5 sigma), of a covariance entry
    # about sd_i sd_j sqrt(2 / n) (6 sigma).
    assert ((emp_mean - mean).abs() <= 5 * sd / n_paths**0.5).all()
    tol_cov = 6 * torch.outer(sd, sd) * (2.0 / n_paths) ** 0.5
    assert ((emp_cov - cov).abs() <= tol_cov).all()


def test_paths_deterministic_and_differentiable(duels):
    X, comp = duels(2, 10, seed=5)
    s = PairwiseGPSurrogate.fit(X, comp, lengthscale=0.25, outputscale=1.0)
    x = torch.rand(5, 2, generator=torch.Generator().manual_seed(2), dtype=torch.float64)
    a = s.sample_paths(3, torch.Generator().manual_seed(9), num_features=64)(x)
    b = s.sample_paths(3, torch.Generator().manual_seed(9), num_features=64)(x)
    c = s.sample_paths(3, torch.Generator().manual_seed(10), num_features=64)(x)
    torch.testing.assert_close(a, b, rtol=0, atol=0)
    assert not torch.allclose(a, c)
    path = s.sample_paths(2, torch.Generator().manual_seed(3), num_features=64)
    x0 = x[:1].clone().requires_grad_(True)
    (grad,) = torch.autograd.grad(path(x0)[0, 1], x0)
    h = 1e-6
    e = torch.tensor([[h, 0.0]], dtype=torch.float64)
    fd = (path(x[:1] + e)[0, 1] - path(x[:1] - e)[0, 1]) / (2 * h)
    torch.testing.assert_close(grad[0, 0], fd, rtol=1e-6, atol=1e-6)
