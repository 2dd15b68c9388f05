"""Posterior sample paths (pathwise conditioning on the Laplace posterior) vs the joint
Laplace posterior ``posterior_mean_cov`` (paper Sec. 4)."""

from __future__ import annotations

import numpy as np
import pytest
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


def _reference_draw_sample_paths(surrogate, num_paths, generator, num_features):
    """The pathwise formula of :mod:`localpbo_core.surrogate.sampling` written directly in
    torch, without the numpy fast route (the reference); the random draws are the module's
    own (:func:`~localpbo_core.surrogate.sampling.path_draws`)."""
    from localpbo_core.surrogate.kernel import se_kernel
    from localpbo_core.surrogate.sampling import path_draws

    X = surrogate.train_inputs
    ls = surrogate.lengthscale
    os_ = surrogate.outputscale
    omega, phase, weights, xi, amp = path_draws(surrogate, num_paths, generator, num_features)

    def prior(x):
        feats = amp * torch.cos(torch.einsum("nd,sfd->nsf", x, omega) + phase)
        return (feats * weights).sum(-1)

    L = surrogate.chol_K
    LB = surrogate.chol_B
    with torch.no_grad():
        noise = torch.linalg.solve_triangular(LB.transpose(0, 1), xi, upper=True)
        f_samples = surrogate.utility.unsqueeze(-1) + L @ noise
        update = torch.cholesky_solve(f_samples - prior(X), L)

    def path(x):
        return prior(x) + se_kernel(x, X, ls, os_) @ update

    return path


def test_paths_equal_the_reference_formula_for_a_fixed_generator(duels):
    X, comp = duels(5, 40, seed=11)
    s = PairwiseGPSurrogate.fit(X, comp)
    x = torch.rand(50, 5, generator=torch.Generator().manual_seed(0), dtype=torch.float64)
    x = torch.cat([x, s.train_inputs[:5]])
    for num_paths, num_features in ((1, 1024), (3, 64)):
        new = s.sample_paths(num_paths, torch.Generator().manual_seed(7), num_features)
        ref_paths = _reference_draw_sample_paths(
            s, num_paths, torch.Generator().manual_seed(7), num_features
        )
        with torch.no_grad():
            ref = ref_paths(x)
            torch.testing.assert_close(new(x), ref, rtol=0, atol=1e-12)
        np.testing.assert_allclose(new.values(x.numpy()), ref.numpy(), rtol=0, atol=1e-12)
        np.testing.assert_allclose(
            new.value_and_grad(x.numpy())[0], ref.numpy(), rtol=0, atol=1e-12
        )


def test_analytic_gradient_matches_autograd_and_finite_differences(duels):
    d = 4
    X, comp = duels(d, 30, seed=12)
    s = PairwiseGPSurrogate.fit(X, comp)
    paths = s.sample_paths(3, torch.Generator().manual_seed(5), num_features=256)
    g = torch.Generator().manual_seed(1)
    x = torch.cat([torch.rand(6, d, generator=g, dtype=torch.float64), s.train_inputs[:2]])
    vals, grads = paths.value_and_grad(x.numpy())
    assert vals.shape == (8, 3) and grads.shape == (8, 3, d)
    # autograd of the torch path, one path at a time (rows are independent)
    xr = x.clone().requires_grad_(True)
    out = paths(xr)
    for j in range(3):
        (ag,) = torch.autograd.grad(out[:, j].sum(), xr, retain_graph=True)
        np.testing.assert_allclose(grads[:, j, :], ag.numpy(), rtol=1e-10, atol=1e-10)
        v_j, g_j = paths.value_and_grad(x.numpy(), j)
        np.testing.assert_array_equal(v_j, vals[:, j])
        np.testing.assert_array_equal(g_j, grads[:, j, :])
    np.testing.assert_allclose(vals, out.detach().numpy(), rtol=0, atol=1e-12)
    # central finite differences of the numpy values
    h = 1e-6
    fd = np.empty_like(grads)
    for i in range(d):
        e = np.zeros(d)
        e[i] = h
        fd[:, :, i] = (paths.values(x.numpy() + e) - paths.values(x.numpy() - e)) / (2 * h)
    scale = np.abs(grads).max()
    np.testing.assert_allclose(grads, fd, rtol=0, atol=1e-6 * max(scale, 1.0))


def test_numpy_route_rejects_bad_input(duels):
    X, comp = duels(2, 8, seed=3)
    s = PairwiseGPSurrogate.fit(X, comp, lengthscale=0.3, outputscale=1.0)
    paths = s.sample_paths(2, torch.Generator().manual_seed(0), num_features=16)
    with pytest.raises(ValueError, match="shape"):
        paths.value_and_grad(np.zeros((3, 3)))
    with pytest.raises(ValueError, match="float64"):
        paths.values(np.zeros((3, 2), dtype=np.float32))
    with pytest.raises(ValueError, match="shape"):
        paths.values(torch.zeros(3, 2, dtype=torch.float64))  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="index"):
        paths.value_and_grad(np.zeros((3, 2)), 2)
    with pytest.raises(ValueError, match="float64"):
        paths(torch.zeros(3, 2, dtype=torch.float32))
