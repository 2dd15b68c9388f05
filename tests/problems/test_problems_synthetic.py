"""Synthetic problems equal BoTorch's test functions, negated, on the mapped box."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from botorch.test_functions.synthetic import Hartmann, Levy, Rosenbrock, StyblinskiTang

from localpbo_core.problems import SyntheticProblem, make_problem

BOTORCH = {
    "hartmann6": (Hartmann, 6),
    "rosenbrock16": (Rosenbrock, 16),
    "levy32": (Levy, 32),
    "styblinskitang32": (StyblinskiTang, 32),
    "styblinskitang64": (StyblinskiTang, 64),
}


@pytest.mark.parametrize("name", sorted(BOTORCH))
def test_equals_negated_botorch_at_random_points(name: str) -> None:
    cls, dim = BOTORCH[name]
    reference = cls(dim=dim, negate=True)
    problem = make_problem(name)
    assert isinstance(problem, SyntheticProblem)
    assert problem.dim == dim
    thetas = np.random.default_rng(42).uniform(size=(50, dim))
    bounds = reference.bounds.numpy()
    native = bounds[0] + (bounds[1] - bounds[0]) * thetas
    expected = reference(torch.tensor(native, dtype=torch.float64)).numpy()
    got = np.array([problem.true_value(t) for t in thetas])
    np.testing.assert_allclose(got, expected, rtol=1e-6, atol=1e-9)
    np.testing.assert_allclose(problem.values(thetas), expected, rtol=1e-6, atol=1e-9)
    np.testing.assert_allclose([problem.to_native(t) for t in thetas[:3]], native[:3])
    assert problem.evaluate(thetas[0], 123) == problem.true_value(thetas[0])


@pytest.mark.parametrize("name", sorted(BOTORCH))
def test_known_optimum(name: str) -> None:
    cls, dim = BOTORCH[name]
    reference = cls(dim=dim, negate=True)
    problem = make_problem(name)
    assert problem.optimal_value == pytest.approx(reference.optimal_value, rel=1e-9)
    theta_star = problem.optimizer
    assert np.all((theta_star >= 0) & (theta_star <= 1))
    np.testing.assert_allclose(
        problem.to_native(theta_star), reference.optimizers[0].numpy(), atol=1e-12
    )
    value = problem.true_value(theta_star)
    assert value == pytest.approx(reference.optimal_value, rel=1e-5, abs=1e-6)
    # the optimum beats every one of many random points
    random_values = problem.values(np.random.default_rng(1).uniform(size=(2000, dim)))
    assert value > random_values.max()


@pytest.mark.parametrize("name", sorted(BOTORCH))
def test_value_range_is_set(name: str) -> None:
    problem = make_problem(name)
    assert np.isfinite(problem.value_range) and problem.value_range > 0


@pytest.mark.parametrize(
    ("theta", "seed", "field"),
    [
        (np.full(5, 0.5), 0, "theta"),
        (np.r_[np.full(5, 0.5), np.nan], 0, "theta"),
        (np.r_[np.full(5, 0.5), 1.01], 0, "theta"),
        (np.full(6, 0.5), -3, "seed"),
    ],
)
def test_bad_inputs_raise(theta: np.ndarray, seed: int, field: str) -> None:
    problem = make_problem("hartmann6")
    with pytest.raises(ValueError, match=field):
        problem.evaluate(theta, seed)
    with pytest.raises(ValueError, match="thetas"):
        problem.values(np.full((3, 5), 0.5))
