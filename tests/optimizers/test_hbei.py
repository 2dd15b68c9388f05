"""HB-EI baseline: improvement without noise, bit-identical reruns, the believed GP and its
EI against independent computations, warm-started chain, options."""

from __future__ import annotations

import numpy as np
import pytest
from optim_helpers import drive, judged, utility
from scipy.stats import norm

from localpbo_core.optimizers import Outcome, available_optimizers, make_optimizer
from localpbo_core.optimizers.hbei import HBEI, expected_improvement
from localpbo_core.validation import SettingError

pytestmark = pytest.mark.usefixtures("one_torch_thread")


def test_registered() -> None:
    assert "hbei" in available_optimizers()
    assert isinstance(make_optimizer("hbei", 2, seed=0, budget=4), HBEI)


def test_improves_on_smooth_2d_problem_without_noise() -> None:
    opt = make_optimizer("hbei", 2, seed=3, budget=22)
    thetas = drive(opt)
    values = np.array([utility(t) for t in thetas])
    initial_best = values[:2].max()
    assert values.max() >= 0.5 * initial_best  # closes half the gap to the optimum (0)
    assert utility(opt.incumbent.theta) > initial_best
    assert len(thetas) == 22 and opt.done
    # king of the hill: every duel after the design is a new point against the winner
    hist = opt.history
    assert all(d.first == i + 1 for i, d in enumerate(hist.duels))


def test_same_seed_and_outcomes_give_bit_identical_candidates() -> None:
    def run(seed: int) -> np.ndarray:
        return np.stack(drive(make_optimizer("hbei", 3, seed=seed, budget=14)))

    a, b = run(5), run(5)
    assert np.array_equal(a, b)
    assert not np.array_equal(a[2:], run(6)[2:])


def test_chain_is_warm_started_and_respects_every_duel() -> None:
    opt = make_optimizer("hbei", 2, seed=0, budget=14, hyperparameter_refit_every=5)
    assert isinstance(opt, HBEI)
    drive(opt)
    chain = opt.chain
    comps = opt.comparisons()
    # the chain's last target: every duel but the final one (proposed before it was answered)
    assert np.array_equal(chain.winners, comps[:-1, 0])
    assert (chain.g > 0).all()
    # 12 iterations, hyperparameters learned at iterations 0, 5, 10: at most three
    # factorisations (a relearn that returns the same values keeps the factor), every other
    # iteration extended the factor by one row
    assert 1 <= chain.full_factorizations <= 3
    assert chain.full_factorizations + chain.extended_rows == 12
    assert opt.surrogate is not None


def test_believed_gp_and_ei_against_an_independent_computation() -> None:
    opt = make_optimizer("hbei", 2, seed=1, budget=9)
    assert isinstance(opt, HBEI)
    drive(opt)
    gp = opt.believed
    assert gp is not None
    chain = opt.chain
    X = chain.X
    # dense reference of the GP of f given g: joint Gaussian, explicit inverse
    ls, s = chain.lengthscale, chain.outputscale
    n = X.shape[0]
    H = np.zeros((chain.num_duels, n))
    H[np.arange(chain.num_duels), chain.winners] = 1.0
    H[np.arange(chain.num_duels), chain.losers] = -1.0

    def k(a: np.ndarray, b: np.ndarray) -> np.ndarray:
        return s * np.exp(-0.5 * (((a[:, None] - b[None]) / ls) ** 2).sum(-1))

    Minv = np.linalg.inv(H @ k(X, X) @ H.T + 2.0 * np.eye(chain.num_duels))
    xq = np.random.default_rng(0).random((6, 2))
    C = k(xq, X) @ H.T
    mu = C @ Minv @ chain.g[0]
    sd = np.sqrt(s - np.einsum("ij,jk,ik->i", C, Minv, C))
    best = 0.1
    ei_ref = (mu - best) * norm.cdf((mu - best) / sd) + sd * norm.pdf((mu - best) / sd)
    ei, grad = expected_improvement(gp, best, xq)
    np.testing.assert_allclose(ei, ei_ref, rtol=1e-9, atol=1e-12)
    h = 1e-6
    for j in range(2):
        e = np.zeros(2)
        e[j] = h
        fd = expected_improvement(gp, best, xq + e)[0] - expected_improvement(gp, best, xq - e)[0]
        np.testing.assert_allclose(grad[:, j], fd / (2 * h), rtol=1e-5, atol=1e-8)


def test_each_ask_duels_one_new_point_against_the_winner() -> None:
    opt = make_optimizer("hbei", 2, seed=0, budget=6)
    values: dict[int, float] = {}
    for _ in range(3):
        ask = opt.ask()
        for c in ask.candidates:
            values[c.id] = utility(c.theta)
        opt.tell(judged(values, ask.duels))
    ask = opt.ask()
    assert len(ask.candidates) == 1 and len(ask.duels) == 1
    assert ask.duels[0].second == opt.incumbent.id


@pytest.mark.parametrize(
    ("option", "value"),
    [
        ("batch_size", 2),
        ("batch_size", True),
        ("num_raw_samples", 0),
        ("num_restarts", 0),
        ("burn_in", -1),
        ("steps_per_iteration", -1),
        ("steps_per_iteration", 1.5),
        ("hyperparameter_refit_every", 0),
    ],
)
def test_bad_options_raise_setting_error(option: str, value: object) -> None:
    with pytest.raises(SettingError) as err:
        make_optimizer("hbei", 2, seed=0, budget=6, **{option: value})
    assert err.value.field == option


def test_restarts_may_not_exceed_raw_samples() -> None:
    with pytest.raises(SettingError) as err:
        make_optimizer("hbei", 2, seed=0, budget=6, num_raw_samples=3, num_restarts=5)
    assert err.value.field == "num_restarts"


@pytest.mark.parametrize(
    ("fixed", "lengthscale", "outputscale"),
    [
        ({"lengthscale": 0.2, "outputscale": 1.0}, [0.2, 0.2], 1.0),
        ({"lengthscale": [0.2, 0.3]}, [0.2, 0.3], 1.0e4),
    ],
)
def test_fixed_hyperparameters_hold_and_the_chain_is_never_restarted(
    fixed: dict, lengthscale: list[float], outputscale: float
) -> None:
    opt = make_optimizer(
        "hbei", 2, seed=1, budget=16, hyperparameter_refit_every=3, hyperparameters=fixed
    )
    assert isinstance(opt, HBEI)
    kernels = []
    while not opt.done:
        batch = opt.ask()
        kernels.append((opt.chain.lengthscale.copy(), opt.chain.outputscale))
        opt.tell([Outcome(d.first, d.second) for d in batch.duels])
    for ls, s in kernels[1:]:  # the first ask is the initial design: no chain yet
        np.testing.assert_array_equal(ls, lengthscale)
        assert s == outputscale
    assert opt.surrogate is not None
    np.testing.assert_array_equal(opt.surrogate.lengthscale.numpy(), lengthscale)
    assert float(opt.surrogate.outputscale) == outputscale
    # one fresh chain, then only extensions: the kernel never changed
    assert opt.chain.full_factorizations == 1


def test_learned_lengthscales_restart_the_chain() -> None:
    opt = make_optimizer("hbei", 2, seed=1, budget=16, hyperparameter_refit_every=3)
    assert isinstance(opt, HBEI)
    drive(opt)
    assert opt.chain.full_factorizations > 1


@pytest.mark.parametrize(
    ("value", "field"),
    [
        ({"lengthscale": -1.0}, "hyperparameters.lengthscale"),
        ({"outputscale": 0.0}, "hyperparameters.outputscale"),
        ({"noise": 0.1}, "hyperparameters.noise"),
    ],
)
def test_bad_hyperparameters_raise_setting_error(value: dict, field: str) -> None:
    with pytest.raises(SettingError) as err:
        make_optimizer("hbei", 2, seed=0, budget=6, hyperparameters=value)
    assert err.value.field == field
