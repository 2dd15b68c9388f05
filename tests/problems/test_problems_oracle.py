"""The noisy preference oracle (paper Sec. 2, eqs. (2)-(3): observation noise and preference)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.stats import norm

from localpbo_core.problems import PreferenceOracle, make_problem


@pytest.fixture
def hartmann():
    return make_problem("hartmann6")


def test_noise_std_matches(hartmann) -> None:
    oracle = PreferenceOracle(hartmann, noise_fraction=0.1, seed=0)
    assert oracle.noise_std == pytest.approx(0.1 * hartmann.value_range)
    pairs = np.array([oracle.noisy_pair(1.0, -2.0) for _ in range(20_000)])
    eps = pairs - np.array([1.0, -2.0])
    np.testing.assert_allclose(eps.mean(axis=0), 0.0, atol=4 * oracle.noise_std / np.sqrt(2e4))
    np.testing.assert_allclose(eps.std(axis=0), oracle.noise_std, rtol=0.03)
    assert abs(np.corrcoef(eps.T)[0, 1]) < 0.03  # independent noise on a and b


def test_win_probability_matches_probit(hartmann) -> None:
    """P(a wins) = Phi((f_a - f_b) / (sqrt(2) sigma)) under paper eqs. (2)-(3)."""
    oracle = PreferenceOracle(hartmann, noise_fraction=0.1, seed=1)
    diff = 0.5 * oracle.noise_std
    n = 20_000
    wins = sum(oracle.compare(1.0 + diff, 1.0) for _ in range(n))
    expected = norm.cdf(diff / (np.sqrt(2) * oracle.noise_std))
    assert wins / n == pytest.approx(expected, abs=4 * np.sqrt(expected * (1 - expected) / n))
    assert oracle.comparisons == n


def test_seeded_reproducibility(hartmann) -> None:
    values = np.random.default_rng(5).normal(size=(200, 2))
    a = PreferenceOracle(hartmann, seed=7)
    b = PreferenceOracle(hartmann, seed=7)
    c = PreferenceOracle(hartmann, seed=8)
    out_a = [a.compare(x, y) for x, y in values]
    out_b = [b.compare(x, y) for x, y in values]
    out_c = [c.compare(x, y) for x, y in values]
    assert out_a == out_b
    assert out_a != out_c


def test_noise_free_oracle_picks_larger(hartmann) -> None:
    oracle = PreferenceOracle(hartmann, noise_fraction=0.0, seed=0)
    values = np.random.default_rng(2).normal(size=(500, 2))
    assert [oracle.compare(x, y) for x, y in values] == [bool(x > y) for x, y in values]
    assert oracle.compare(1.0, 1.0) is False  # paper eq. (3): ties go to the second input


def test_duel_evaluates_both(hartmann) -> None:
    oracle = PreferenceOracle(hartmann, noise_fraction=0.0, seed=0)
    good, bad = hartmann.optimizer, np.zeros(6)
    duel = oracle.duel(good, 0, bad, 1)
    assert duel.a_wins is True
    assert duel.value_a == hartmann.true_value(good)
    assert oracle.duel(bad, 0, good, 1).a_wins is False


def test_bad_options_raise(hartmann) -> None:
    with pytest.raises(ValueError, match="noise_fraction"):
        PreferenceOracle(hartmann, noise_fraction=-0.1)
    with pytest.raises(ValueError, match="noise_fraction"):
        PreferenceOracle(hartmann, noise_fraction=float("nan"))
    with pytest.raises(ValueError, match="seed"):
        PreferenceOracle(hartmann, seed=-1)
    with pytest.raises(ValueError, match="value_a"):
        PreferenceOracle(hartmann).compare(float("nan"), 0.0)
    with pytest.raises(ValueError, match="value_range"):
        PreferenceOracle(make_problem("hopper", alive_bonus=True), noise_fraction=0.1)
