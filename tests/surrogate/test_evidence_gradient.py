"""Analytic gradient of the Laplace evidence (laplace.log_evidence_and_kernel_gradient and
hyperparameters.evaluate_with_gradient) against autograd through the differentiable Newton step
(hyperparameters.evaluate), finite differences, and the autograd-driven fit."""

from __future__ import annotations

import math

import pytest
import torch
from surrogate_helpers import learn_kwargs

from localpbo_core.surrogate.data import consolidate
from localpbo_core.surrogate.hyperparameters import (
    evaluate,
    evaluate_with_gradient,
    learn_hyperparameters,
)
from localpbo_core.surrogate.laplace import (
    find_map,
    gram,
    hessian_weight_slope,
    hessian_weights,
    probit_terms,
)


def _problem(duels, d: int, n: int, seed: int):
    X, comp = duels(d, n, seed, scale=6.0)
    data = consolidate(X, comp)
    g = torch.Generator().manual_seed(1000 + seed)
    ls = 0.05 + 0.45 * torch.rand(d, generator=g, dtype=torch.float64)
    return data, ls


def _autograd(data, ls, os_, z_limit):
    theta = torch.cat([ls.log(), torch.tensor([math.log(os_)], dtype=torch.float64)])
    theta.requires_grad_(True)
    f0 = torch.zeros(data.X.shape[0], dtype=torch.float64)
    d = ls.shape[0]
    value, _, _ = evaluate(
        data.X, data.winners, data.losers, theta[:d].exp(), theta[d].exp(), f0, 1e-8, z_limit
    )
    value.backward()
    return float(value.detach()), theta.grad


@pytest.mark.parametrize(
    ("d", "n", "outputscale", "z_limit", "form"),
    [
        (1, 10, 2.0, None, "whitened"),
        (3, 25, 3.7, None, "whitened"),
        (8, 45, 0.7, None, "whitened"),
        (20, 60, 5.0, None, "whitened"),
        (4, 40, 60.0, 3.0, "whitened"),
        (9, 50, 80.0, 3.0, "whitened"),
        (1, 10, 2.0, None, "duels"),
        (3, 25, 3.7, None, "duels"),
        (8, 45, 0.7, None, "duels"),
        (20, 60, 5.0, None, "duels"),
        (6, 50, 90.0, None, "duels"),
    ],
)
def test_analytic_gradient_matches_autograd(duels, d, n, outputscale, z_limit, form):
    data, ls = _problem(duels, d, n, seed=d)
    f0 = torch.zeros(data.X.shape[0], dtype=torch.float64)
    value, g_ls, g_os, f_hat = evaluate_with_gradient(
        data.X, data.winners, data.losers, ls, outputscale, f0, 1e-8, z_limit, form=form
    )
    if z_limit is not None:  # the clamped branch must actually be exercised
        t = probit_terms(f_hat, data.winners, data.losers, z_limit)
        assert 0 < int((~t.active).sum()) < t.active.numel()
    ref_value, ref_grad = _autograd(data, ls, outputscale, z_limit)
    grad = torch.cat([g_ls, g_os.reshape(1)])
    assert abs(value - ref_value) <= 1e-10 * (1.0 + abs(ref_value))
    torch.testing.assert_close(grad, ref_grad, rtol=0, atol=1e-8 * float(ref_grad.abs().max()))


@pytest.mark.parametrize("form", ["whitened", "duels"])
def test_analytic_gradient_matches_finite_differences(duels, form):
    data, ls = _problem(duels, 5, 30, seed=2)
    os_ = 2.5
    f0 = torch.zeros(data.X.shape[0], dtype=torch.float64)

    def value(log_ls, log_os):
        return evaluate_with_gradient(
            data.X,
            data.winners,
            data.losers,
            log_ls.exp(),
            math.exp(log_os),
            f0,
            1e-8,
            None,
            form=form,
        )[0]

    _, g_ls, g_os, _ = evaluate_with_gradient(
        data.X, data.winners, data.losers, ls, os_, f0, 1e-8, None, form=form
    )
    h = 1e-5
    base = ls.log()
    fd = [
        (value(base + h * e, math.log(os_)) - value(base - h * e, math.log(os_))) / (2 * h)
        for e in torch.eye(5, dtype=torch.float64)
    ]
    fd.append((value(base, math.log(os_) + h) - value(base, math.log(os_) - h)) / (2 * h))
    grad = torch.cat([g_ls, g_os.reshape(1)])
    torch.testing.assert_close(grad, torch.tensor(fd, dtype=torch.float64), rtol=0, atol=1e-7)


@pytest.mark.parametrize("z_limit", [None, 3.0])
def test_analytic_and_autograd_fits_reach_the_same_optimum(duels, z_limit):
    X, comp = duels(4, 35, 5, scale=5.0)
    data = consolidate(X, comp)
    kw = learn_kwargs(data, z_limit=z_limit)
    fast = learn_hyperparameters(data.X, data.winners, data.losers, **kw)
    ref = learn_hyperparameters(data.X, data.winners, data.losers, analytic_gradient=False, **kw)
    assert abs(fast.log_marginal_likelihood - ref.log_marginal_likelihood) < 1e-7
    torch.testing.assert_close(fast.lengthscale, ref.lengthscale, rtol=0, atol=1e-3)
    assert abs(math.log(fast.outputscale / ref.outputscale)) < 1e-3
    # the reported MAP is converged at the tight tolerance
    v_ref, _ = find_map(fast.L, data.winners, data.losers, fast.v_hat, z_limit, tol=1e-13)
    torch.testing.assert_close(fast.v_hat, v_ref, rtol=0, atol=1e-9)


def test_hessian_weight_slope_matches_autograd():
    z = torch.linspace(-12.0, 8.0, 81, dtype=torch.float64)
    winners, losers = torch.arange(81), torch.full((81,), 81)

    def terms(zz):  # duel n compares point n (f = sqrt(2) z_n) with point 81 (f = 0)
        f = torch.cat([zz * math.sqrt(2.0), torch.zeros(1, dtype=torch.float64)])
        return probit_terms(f, winners, losers, None)

    ref = torch.func.jacrev(lambda zz: hessian_weights(terms(zz)))(z).diagonal()
    # z + h cancels for very negative z (in both forms): 1e-7 relative over [-12, 8]
    torch.testing.assert_close(hessian_weight_slope(terms(z)), ref, rtol=1e-7, atol=1e-12)


def test_gram_is_the_symmetric_product():
    Y = torch.randn(37, 23, generator=torch.Generator().manual_seed(3), dtype=torch.float64)
    torch.testing.assert_close(gram(Y), Y.T @ Y, rtol=1e-13, atol=1e-12)
    assert torch.equal(gram(Y), gram(Y).T)
