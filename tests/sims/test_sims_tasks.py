"""Linear-policy tasks: ARS reference returns, seeding, box mapping, true value, errors."""

from __future__ import annotations

import numpy as np
import pytest
from localpbo_sims import (
    TRUE_VALUE_SEEDS,
    LinearPolicyTask,
    available_tasks,
    load_ars_policy,
    make_task,
)


@pytest.fixture(scope="module")
def hopper() -> LinearPolicyTask:
    return make_task("hopper")


@pytest.fixture(scope="module")
def hopper_alive() -> LinearPolicyTask:
    return make_task("hopper", alive_bonus=True)


@pytest.fixture(scope="module")
def swimmer() -> LinearPolicyTask:
    return make_task("swimmer")


def test_dimensions() -> None:
    assert available_tasks() == ["hopper", "swimmer", "walker2d"]
    assert make_task("hopper").dim == 33
    assert make_task("walker2d").dim == 102
    assert make_task("swimmer").dim == 16


@pytest.mark.parametrize(
    ("name", "low", "high"), [("hopper", 1490.0, 1570.0), ("walker2d", 10_100.0, 10_370.0)]
)
def test_ars_policy_known_returns(name: str, low: float, high: float) -> None:
    """ARS's published policies reach their known returns (alive bonus kept; mean over the
    true-value reset seeds, single episodes vary more), and removing the alive bonus subtracts
    exactly one per healthy step (same trajectory)."""
    ars = load_ars_policy(name)
    kept = make_task(name, alive_bonus=True)
    removed = make_task(name)
    returns = []
    for seed in TRUE_VALUE_SEEDS:
        with_bonus = kept.rollout_weights(ars.weights, seed)
        without = removed.rollout_weights(ars.weights, seed)
        returns.append(with_bonus.episode_return)
        assert with_bonus.episode_return > 0.7 * low
        assert without.steps == with_bonus.steps
        healthy_steps = with_bonus.steps - int(with_bonus.terminated)
        assert with_bonus.episode_return - without.episode_return == pytest.approx(
            healthy_steps, abs=1e-6
        )
    assert low <= np.mean(returns) <= high


def test_evaluate_is_deterministic_per_seed(hopper: LinearPolicyTask) -> None:
    theta = hopper.theta_from_weights(load_ars_policy("hopper").weights).theta
    a = hopper.evaluate(theta, 5)
    assert hopper.evaluate(theta, 5) == a
    assert make_task("hopper").evaluate(theta, 5) == a
    assert hopper.evaluate(theta, 6) != a


def test_true_value_is_mean_over_fixed_seeds(swimmer: LinearPolicyTask) -> None:
    theta = np.random.default_rng(3).uniform(size=swimmer.dim)
    expected = np.mean([swimmer.evaluate(theta, s) for s in TRUE_VALUE_SEEDS])
    assert swimmer.true_value(theta) == pytest.approx(expected, rel=0, abs=1e-12)
    assert swimmer.true_value(theta.copy()) == swimmer.true_value(theta)  # cached path
    uncached = make_task("swimmer", cache_size=0)
    assert uncached.true_value(theta) == swimmer.true_value(theta)


def test_box_mapping_round_trip(hopper: LinearPolicyTask) -> None:
    theta = np.random.default_rng(0).uniform(size=hopper.dim)
    weights = hopper.policy_from_theta(theta)
    assert weights.shape == (3, 11)
    np.testing.assert_allclose(weights.ravel(), -1.0 + 2.0 * theta)
    np.testing.assert_allclose(hopper.to_native(theta), weights.ravel())
    back = hopper.theta_from_weights(weights)
    np.testing.assert_allclose(back.theta, theta, atol=1e-15)
    assert back.n_clipped == 0
    np.testing.assert_allclose(hopper.policy_from_theta(np.zeros(33)), -np.ones((3, 11)))
    np.testing.assert_allclose(hopper.policy_from_theta(np.ones(33)), np.ones((3, 11)))


def test_theta_from_weights_reports_clipping(hopper: LinearPolicyTask) -> None:
    ars = load_ars_policy("hopper").weights
    result = hopper.theta_from_weights(ars)
    outside = np.abs(ars.ravel()) > 1.0
    assert result.n_clipped == int(outside.sum()) > 0
    np.testing.assert_array_equal(result.clipped, outside)
    np.testing.assert_allclose(
        hopper.policy_from_theta(result.theta).ravel(), np.clip(ars.ravel(), -1, 1)
    )
    wide = make_task("hopper", weight_low=-2.0, weight_high=2.0, value_range=200.0)
    assert wide.theta_from_weights(ars).n_clipped == 0
    assert wide.value_range == 200.0


def test_value_range_defined_only_for_the_calibrated_definition(
    hopper: LinearPolicyTask, hopper_alive: LinearPolicyTask
) -> None:
    assert np.isfinite(hopper.value_range) and hopper.value_range > 0
    assert np.isnan(hopper_alive.value_range)
    # swimmer has no alive bonus, so the option does not change its definition
    assert make_task("swimmer", alive_bonus=True).value_range == make_task("swimmer").value_range


@pytest.mark.parametrize(
    ("theta", "field"),
    [
        (np.full(32, 0.5), "theta"),
        (np.full((1, 33), 0.5), "theta"),
        (np.r_[np.full(32, 0.5), np.nan], "theta"),
        (np.r_[np.full(32, 0.5), 1.5], "theta"),
        (np.r_[np.full(32, 0.5), -0.1], "theta"),
    ],
)
def test_bad_theta_raises(hopper: LinearPolicyTask, theta: np.ndarray, field: str) -> None:
    with pytest.raises(ValueError, match=field):
        hopper.evaluate(theta, 0)
    with pytest.raises(ValueError, match=field):
        hopper.true_value(theta)


def test_bad_options_raise(hopper: LinearPolicyTask) -> None:
    with pytest.raises(ValueError, match=r"name.*valid"):
        make_task("cheetah")
    with pytest.raises(ValueError, match="seed"):
        hopper.evaluate(np.full(33, 0.5), -1)
    with pytest.raises(ValueError, match="seed"):
        hopper.evaluate(np.full(33, 0.5), 1.5)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="weights"):
        hopper.theta_from_weights(np.zeros((11, 3)))
    with pytest.raises(ValueError, match="weights"):
        hopper.theta_from_weights(np.full(33, np.nan))
    with pytest.raises(ValueError, match="weight_low"):
        make_task("hopper", weight_low=1.0, weight_high=-1.0)
    with pytest.raises(ValueError, match="episode_steps"):
        make_task("hopper", episode_steps=0)
    with pytest.raises(ValueError, match="value_range"):
        make_task("hopper", value_range=-1.0)
    with pytest.raises(ValueError, match="weight_low"):
        make_task("hopper", weight_low="a")
    with pytest.raises(ValueError, match="cache_size"):
        make_task("hopper", cache_size=-1)
    with pytest.raises(ValueError, match="alive_bonus"):
        make_task("hopper", alive_bonus=1)
