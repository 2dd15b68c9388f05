"""The lean MuJoCo runner reproduces gymnasium's v5 environments step by step."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from localpbo_sims import (
    HOPPER_V5,
    INVERTED_PENDULUM_V5,
    SWIMMER_V5,
    WALKER2D_V5,
    EnvSpec,
    EpisodeRunner,
    load_ars_policy,
)

# A cart-pole gain that balances for a while (found by random search in [-3, 3]^4).
PENDULUM_GAIN = np.array([[0.15360579, 2.77663795, 0.17435185, 0.3615617]])


def _policy(spec: EnvSpec) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    if spec.env_id == "Hopper-v5":
        ars = load_ars_policy("hopper")
        return ars.weights, ars.obs_mean, ars.obs_std
    if spec.env_id == "Walker2d-v5":
        ars = load_ars_policy("walker2d")
        return ars.weights, ars.obs_mean, ars.obs_std
    if spec.env_id == "Swimmer-v5":
        w = np.random.default_rng(7).uniform(-1.0, 1.0, size=(2, 8))
        return w, np.zeros(8), np.ones(8)
    return PENDULUM_GAIN, np.zeros(4), np.ones(4)


CASES = [
    (HOPPER_V5, {}),
    (HOPPER_V5, {"healthy_reward": 0.0}),
    (WALKER2D_V5, {}),
    (WALKER2D_V5, {"healthy_reward": 0.0}),
    (SWIMMER_V5, {}),
    (INVERTED_PENDULUM_V5, {}),
]


CASE_IDS = ["hopper", "hopper-no-alive", "walker2d", "walker2d-no-alive", "swimmer", "pendulum"]


@pytest.mark.parametrize(("spec", "kwargs"), CASES, ids=CASE_IDS)
@pytest.mark.parametrize("seed", [0, 11])
def test_step_by_step_equal_to_gymnasium(spec: EnvSpec, kwargs: dict, seed: int) -> None:
    spec = EnvSpec(**{**spec.__dict__, **kwargs})
    weights, mean, std = _policy(spec)
    runner = EpisodeRunner(spec)
    env = gym.make(spec.env_id, **kwargs)
    try:
        obs_gym, _ = env.reset(seed=seed)
        obs = runner.reset(seed)
        np.testing.assert_allclose(obs, obs_gym, rtol=0, atol=1e-9)
        total_gym, steps = 0.0, 0
        while True:
            action = weights @ ((obs_gym - mean) / std)
            obs_gym, reward_gym, term_gym, trunc_gym, _ = env.step(action)
            obs, reward, term = runner.step(action)
            steps += 1
            total_gym += reward_gym
            np.testing.assert_allclose(obs, obs_gym, rtol=0, atol=1e-9, err_msg=f"step {steps}")
            assert reward == pytest.approx(reward_gym, abs=1e-9), f"step {steps}"
            assert term == term_gym, f"step {steps}"
            if term_gym or trunc_gym:
                break
    finally:
        env.close()
    result = runner.run_linear(weights, mean, std, seed=seed)
    assert result.steps == steps
    assert result.terminated == term_gym
    assert result.episode_return == pytest.approx(total_gym, rel=0, abs=1e-9)
    assert steps > 20  # the policies chosen here do not fall at once: a meaningful comparison


def test_runner_dimensions() -> None:
    assert (EpisodeRunner(HOPPER_V5).obs_dim, EpisodeRunner(HOPPER_V5).action_dim) == (11, 3)
    assert (EpisodeRunner(WALKER2D_V5).obs_dim, EpisodeRunner(WALKER2D_V5).action_dim) == (17, 6)
    assert (EpisodeRunner(SWIMMER_V5).obs_dim, EpisodeRunner(SWIMMER_V5).action_dim) == (8, 2)
    assert EpisodeRunner(INVERTED_PENDULUM_V5).obs_dim == 4
