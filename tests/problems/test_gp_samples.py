"""GP sample-path problems (paper App. D.4): determinism, protocol, accuracy against an exact
GP draw (empirical covariance over many paths; whitened values of single paths)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

from localpbo_core.problems import Problem, available_problems, make_problem
from localpbo_core.problems.gp_samples import (
    DEFAULT_FEATURES,
    GPSampleProblem,
    draw_features,
    sobol_value_range,
)
from localpbo_core.validation import SettingError

D = 8
_RNG = np.random.default_rng(20260101)
# half spread over the cube, half in a small corner: correlations from ~0 to ~1 at l = 0.5
POINTS = np.concatenate([_RNG.random((60, D)), 0.5 + 0.25 * _RNG.random((60, D))])


def se_kernel(X: np.ndarray, lengthscale: float) -> np.ndarray:
    d2 = ((X[:, None, :] - X[None, :, :]) ** 2).sum(-1)
    return np.exp(-d2 / (2.0 * lengthscale**2))


def path_values(X: np.ndarray, lengthscale: float, instance: int, features: int) -> np.ndarray:
    omega, phase, weights = draw_features(X.shape[1], lengthscale, instance, features)
    return np.cos(X @ omega.T + phase) @ weights


def covariance_z(samples: np.ndarray, K: np.ndarray) -> float:
    """max |z| of the empirical covariance (known zero mean) against ``K``; each entry's
    Monte Carlo std is sqrt((K_ii K_jj + K_ij^2) / N)."""
    n = samples.shape[0]
    C = samples.T @ samples / n
    diag = np.diag(K)
    return float(np.max(np.abs(C - K) / np.sqrt((np.outer(diag, diag) + K**2) / n)))


@pytest.fixture(scope="module")
def many_paths() -> dict[float, np.ndarray]:
    """1500 independent paths (256 features each) per lengthscale at ``POINTS``."""
    return {
        ls: np.stack([path_values(POINTS, ls, 10_000 + i, 256) for i in range(1500)])
        for ls in (0.1, 0.5)
    }


@pytest.mark.parametrize("lengthscale", [0.1, 0.5])
def test_empirical_covariance_matches_se_kernel(many_paths, lengthscale: float) -> None:
    # 7260 distinct entries; under the null max |z| is about 4-4.5
    assert covariance_z(many_paths[lengthscale], se_kernel(POINTS, lengthscale)) < 5.5


@pytest.mark.parametrize("lengthscale", [0.1, 0.5])
def test_covariance_check_detects_a_wrong_lengthscale(many_paths, lengthscale: float) -> None:
    """The check above can fail: the same paths against a 30% longer lengthscale."""
    assert covariance_z(many_paths[lengthscale], se_kernel(POINTS, 1.3 * lengthscale)) > 5.5


def whitened(lengthscale: float, kernel_lengthscale: float, paths: int = 20) -> np.ndarray:
    """Values of single production paths (4096 features) whitened by the exact kernel matrix
    on its well-conditioned eigen-directions (eigenvalue >= 1% of the largest)."""
    lam, U = np.linalg.eigh(se_kernel(POINTS, kernel_lengthscale))
    keep = lam >= 0.01 * lam.max()
    z = [
        U[:, keep].T @ path_values(POINTS, lengthscale, inst, DEFAULT_FEATURES) / np.sqrt(lam[keep])
        for inst in range(paths)
    ]
    return np.concatenate(z)


@pytest.mark.parametrize("lengthscale", [0.1, 0.5])
def test_single_paths_whiten_to_standard_normal(lengthscale: float) -> None:
    z = whitened(lengthscale, lengthscale)
    assert stats.kstest(z, "norm").pvalue > 1e-3
    chi = (np.sum(z**2) - z.size) / np.sqrt(2 * z.size)  # sum z^2 ~ chi^2_n
    assert abs(chi) < 4.0


def test_whitening_check_detects_a_wrong_lengthscale() -> None:
    z = whitened(0.1, 0.13)
    chi = (np.sum(z**2) - z.size) / np.sqrt(2 * z.size)
    assert abs(chi) > 4.0


def test_registered_and_protocol() -> None:
    assert "gp_sample" in available_problems()
    p = make_problem("gp_sample", dim=4, lengthscale=0.5, instance=2)
    assert isinstance(p, Problem) and isinstance(p, GPSampleProblem)
    assert p.name == "gp_sample" and p.dim == 4
    assert p.hyperparameters == {"lengthscale": 0.5, "outputscale": 1.0}
    rng = np.random.default_rng(0)
    for theta in rng.random((20, 4)):
        v = p.evaluate(theta, 3)
        assert v == p.evaluate_native(p.to_native(theta), 7) == p.true_value(theta)
        assert np.isclose(v, p.values(theta[None])[0], rtol=0, atol=1e-12)
    assert p.value_range == sobol_value_range(p) > 0


def test_deterministic_per_dim_lengthscale_instance() -> None:
    theta = np.full(4, 0.3)
    a = make_problem("gp_sample", dim=4, lengthscale=0.5, instance=1)
    fresh = draw_features(4, 0.5, 1)
    np.testing.assert_array_equal(a.omega, fresh[0])
    np.testing.assert_array_equal(a.weights, fresh[2])
    values = {
        (ls, inst): make_problem("gp_sample", dim=4, lengthscale=ls, instance=inst).true_value(
            theta
        )
        for ls in (0.1, 0.5)
        for inst in (0, 1)
    }
    assert len(set(values.values())) == 4  # every (l, instance) is another function
    assert values[(0.5, 1)] == a.true_value(theta)


@pytest.mark.parametrize(
    ("options", "field"),
    [
        ({"lengthscale": 0.1}, "problem_options.dim"),
        ({"dim": 4}, "problem_options.lengthscale"),
        ({"dim": 0, "lengthscale": 0.1}, "problem_options.dim"),
        ({"dim": 4, "lengthscale": -0.1}, "problem_options.lengthscale"),
        ({"dim": 4, "lengthscale": 0.1, "instance": -1}, "problem_options.instance"),
        ({"dim": 4, "lengthscale": 0.1, "noise": 0.1}, "problem_options.noise"),
    ],
)
def test_bad_options_name_the_field(options: dict, field: str) -> None:
    from localpbo_core.session import build_problem
    from localpbo_core.settings import RunSettings

    with pytest.raises(SettingError) as info:
        build_problem(RunSettings("sobol", "gp_sample", problem_options=options))
    assert info.value.field == field


def test_evaluate_native_refuses_points_outside_the_box() -> None:
    p = make_problem("gp_sample", dim=3, lengthscale=0.5)
    with pytest.raises(SettingError):
        p.evaluate_native(np.array([0.5, 0.5, 1.5]), 0)
