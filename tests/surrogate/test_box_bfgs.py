"""The box-constrained BFGS with carried curvature against scipy's L-BFGS-B and closed forms."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.optimize
import torch

from localpbo_core.surrogate import PairwiseGPSurrogate, pairwise_gp
from localpbo_core.surrogate.box_bfgs import minimize_box_bfgs, projected_gradient


def _quadratic(A: np.ndarray, b: np.ndarray):
    def fun(x: np.ndarray) -> tuple[float, np.ndarray]:
        return float(0.5 * x @ A @ x - b @ x), A @ x - b

    return fun


def _spd(n: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    Q, _ = np.linalg.qr(rng.normal(size=(n, n)))
    return Q @ np.diag(np.geomspace(0.1, 30.0, n)) @ Q.T


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_bound_constrained_quadratic_matches_lbfgsb(seed: int) -> None:
    n = 8
    A = _spd(n, seed)
    b = np.random.default_rng(seed + 10).normal(scale=5.0, size=n)
    lo, hi = -np.ones(n), np.ones(n)  # the unconstrained minimiser lies outside: bounds active
    fun = _quadratic(A, b)
    ours = minimize_box_bfgs(fun, np.zeros(n), lo, hi, gtol=1e-9, ftol=0.0)
    ref = scipy.optimize.minimize(
        fun,
        np.zeros(n),
        jac=True,
        method="L-BFGS-B",
        bounds=list(zip(lo, hi, strict=True)),
        options={"ftol": 0.0, "gtol": 1e-10, "maxiter": 1000},
    )
    assert ours.converged
    assert np.any(np.isclose(ours.x, lo) | np.isclose(ours.x, hi))
    np.testing.assert_allclose(ours.x, ref.x, atol=1e-6)
    assert ours.f <= ref.fun + 1e-10
    assert np.max(np.abs(projected_gradient(ours.x, ours.g, lo, hi))) <= 1e-7


def test_exact_hessian_as_start_takes_one_step_on_a_quadratic() -> None:
    n = 6
    A = _spd(n, 3)
    b = np.linspace(-1.0, 1.0, n)
    x_star = np.linalg.solve(A, b)
    lo, hi = x_star - 10.0, x_star + 10.0
    res = minimize_box_bfgs(_quadratic(A, b), np.zeros(n), lo, hi, hessian0=A, gtol=1e-8)
    assert res.n_evaluations == 2  # the start and the Newton point
    np.testing.assert_allclose(res.x, x_star, atol=1e-10)
    # without the curvature the same problem needs many more evaluations
    cold = minimize_box_bfgs(_quadratic(A, b), np.zeros(n), lo, hi, gtol=1e-8)
    np.testing.assert_allclose(cold.x, x_star, atol=1e-6)
    assert cold.n_evaluations > res.n_evaluations


def test_rosenbrock_in_a_box_matches_lbfgsb() -> None:
    def rosen(x: np.ndarray) -> tuple[float, np.ndarray]:
        return float(scipy.optimize.rosen(x)), scipy.optimize.rosen_der(x)

    lo, hi = np.full(5, -2.0), np.full(5, 0.8)  # the minimiser (1, ..., 1) is cut off
    x0 = np.full(5, -1.0)
    ours = minimize_box_bfgs(rosen, x0, lo, hi, maxiter=2000, ftol=0.0, gtol=1e-9)
    ref = scipy.optimize.minimize(
        rosen,
        x0,
        jac=True,
        method="L-BFGS-B",
        bounds=list(zip(lo, hi, strict=True)),
        options={"ftol": 0.0, "gtol": 1e-10, "maxiter": 5000},
    )
    assert ours.f <= ref.fun + 1e-8
    np.testing.assert_allclose(ours.x, ref.x, atol=1e-5)
    assert np.all(ours.x >= lo) and np.all(ours.x <= hi)
    # the learned curvature is symmetric positive definite
    np.testing.assert_allclose(ours.hessian, ours.hessian.T)
    assert np.linalg.eigvalsh(ours.hessian).min() > 0


def test_line_search_backs_off_from_non_finite_values() -> None:
    def fun(x: np.ndarray) -> tuple[float, np.ndarray]:
        if x[0] > 0.5:
            return float("inf"), np.full(1, np.nan)
        return float((x[0] - 0.4) ** 2), 2.0 * (x - 0.4)

    res = minimize_box_bfgs(fun, np.array([-3.0]), np.array([-5.0]), np.array([5.0]), gtol=1e-9)
    np.testing.assert_allclose(res.x, [0.4], atol=1e-6)


def test_bad_inputs_are_refused() -> None:
    fun = _quadratic(np.eye(2), np.zeros(2))
    with pytest.raises(ValueError, match="hessian0"):
        minimize_box_bfgs(fun, np.zeros(2), -np.ones(2), np.ones(2), hessian0=np.eye(3))

    def nan_fun(x: np.ndarray) -> tuple[float, np.ndarray]:
        return float("nan"), np.zeros_like(x)

    with pytest.raises(ValueError, match="not finite at the start"):
        minimize_box_bfgs(nan_fun, np.zeros(2), -np.ones(2), np.ones(2))


def _duels(n: int, d: int, seed: int) -> tuple[torch.Tensor, torch.Tensor]:
    gen = torch.Generator().manual_seed(seed)
    X = torch.rand(n, d, generator=gen, dtype=torch.float64)
    u = -((X - 0.4) ** 2).sum(-1) * 20.0 + 0.3 * torch.randn(n, generator=gen, dtype=torch.float64)
    i = torch.arange(n - 1)
    first_wins = u[i] > u[i + 1]
    comps = torch.stack([torch.where(first_wins, i, i + 1), torch.where(first_wins, i + 1, i)], 1)
    return X, comps


def test_carried_bfgs_and_lbfgsb_reach_the_same_fit_along_a_chain_of_refits() -> None:
    """Cold fit, then warm refits with one more duel each (TuRPBO's pattern): the carried
    curvature solver ends at the optimum L-BFGS-B finds, in no more evaluations overall."""
    X, comps = _duels(60, 4, seed=5)
    fits = {}
    for solver in ("carried-bfgs", "l-bfgs-b"):
        s = PairwiseGPSurrogate.fit(X[:50], comps[:49], solver=solver)
        chain = [s]
        for m in range(50, 59):
            s = PairwiseGPSurrogate.fit(X[: m + 1], comps[:m], warm_start=s, solver=solver)
            chain.append(s)
        fits[solver] = chain
    for ours, ref in zip(fits["carried-bfgs"], fits["l-bfgs-b"], strict=True):
        assert ours.log_marginal_likelihood >= ref.log_marginal_likelihood - 1e-5
        np.testing.assert_allclose(ours.lengthscale, ref.lengthscale, rtol=2e-2)
        np.testing.assert_allclose(ours.outputscale, ref.outputscale, rtol=2e-2)
    assert fits["carried-bfgs"][-1].fit_curvature is not None
    assert fits["l-bfgs-b"][-1].fit_curvature is None
    total = {k: sum(s.n_evaluations for s in v[1:]) for k, v in fits.items()}
    assert total["carried-bfgs"] <= total["l-bfgs-b"]


def test_unknown_solver_is_refused() -> None:
    X, comps = _duels(10, 2, seed=0)
    with pytest.raises(ValueError, match="solver"):
        PairwiseGPSurrogate.fit(X, comps, solver="newton")


def _flat_basin_case() -> tuple[torch.Tensor, torch.Tensor, PairwiseGPSurrogate]:
    """8 noisy duels in 2-D whose evidence has a flat local basin (outputscale at the prior's
    lower edge) next to a better informative one; plus a fit sitting in the flat basin."""
    g = torch.Generator().manual_seed(147)
    X = torch.rand(8, 2, generator=g, dtype=torch.float64)
    u = -8 * ((X - 0.7) ** 2).sum(-1) + 0.7 * torch.randn(8, generator=g, dtype=torch.float64)
    i = torch.arange(7)
    w = u[i + 1] > u[i]
    comps = torch.stack([torch.where(w, i + 1, i), torch.where(w, i, i + 1)], 1)
    flat = PairwiseGPSurrogate.fit(X, comps, lengthscale=0.5, outputscale=0.01)
    return X, comps, flat


def test_a_warm_fit_stuck_in_the_flat_basin_is_checked_against_the_default_start(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    X, comps, flat = _flat_basin_case()
    cold = PairwiseGPSurrogate.fit(X, comps)  # from BoTorch's initial values
    warm = PairwiseGPSurrogate.fit(X, comps, warm_start=flat)
    assert warm.outputscale > 0.1
    assert warm.log_marginal_likelihood >= cold.log_marginal_likelihood - 1e-9
    # without the check the warm-started local solve stays in the worse flat basin
    monkeypatch.setattr(pairwise_gp, "_FLAT_OUTPUTSCALE", 0.0)
    stuck = PairwiseGPSurrogate.fit(X, comps, warm_start=flat)
    assert stuck.outputscale < 0.1
    assert stuck.log_marginal_likelihood < warm.log_marginal_likelihood - 0.1
    assert warm.n_evaluations > stuck.n_evaluations  # both solves are counted
