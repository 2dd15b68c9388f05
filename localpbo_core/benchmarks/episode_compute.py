"""Speed and tunability figures of the linear-policy tasks (prints numbers, asserts nothing).

Usage: ``python -m localpbo_core.benchmarks.episode_compute`` (``--quick``: fewer repetitions).

Prints, per task: steps/s of the lean runner and of gymnasium's env on the same policy and
seed, seconds per full evaluation (one ``evaluate`` episode plus ``true_value``'s 5 episodes,
uncached) for the ARS policy and for random thetas, and for the swimmer demo task the
best-seen ``true_value`` after 2 and after 40 random evaluations (does tuning visibly help
within ~40 evaluations?).
"""

from __future__ import annotations

import argparse
import time
from typing import Any

import gymnasium as gym
import numpy as np
from localpbo_sims.ars import load_ars_policy
from localpbo_sims.tasks import LinearPolicyTask, make_task


def _gym_steps_per_second(task: LinearPolicyTask, weights: np.ndarray, seed: int) -> float:
    kwargs: dict[str, Any] = {} if task.spec.kind != "planar_walker" else {"healthy_reward": 0.0}
    env = gym.make(task.spec.env_id, **kwargs)
    obs, _ = env.reset(seed=seed)
    steps = 0
    start = time.perf_counter()
    while True:
        obs, _, terminated, truncated, _ = env.step(
            weights @ ((obs - task.obs_mean) / task.obs_std)
        )
        steps += 1
        if terminated or truncated:
            break
    elapsed = time.perf_counter() - start
    env.close()
    return steps / elapsed


def speed(name: str, repeats: int) -> None:
    """Print runner speed, gymnasium speed and seconds per evaluation for one task."""
    task = make_task(name, cache_size=0)
    if name in ("hopper", "walker2d"):
        weights = load_ars_policy(name).weights
        label = "ARS policy"
    else:
        weights = np.random.default_rng(0).uniform(-1, 1, (task.action_dim, task.obs_dim))
        label = "random policy"
    steps = 0
    start = time.perf_counter()
    for seed in range(repeats):
        steps += task.rollout_weights(weights, seed).steps
    lean = steps / (time.perf_counter() - start)
    ref = np.mean([_gym_steps_per_second(task, weights, s) for s in range(repeats)])
    print(f"{name}: lean runner {lean:,.0f} steps/s, gymnasium {ref:,.0f} steps/s ({label})")
    full = 6 * task.episode_steps / lean
    print(f"{name}: a policy that never falls costs about {full:.2f} s per evaluation (6 episodes)")

    theta = task.theta_from_weights(weights).theta
    if name in ("hopper", "walker2d"):
        label = "ARS policy clipped into the box"
    start = time.perf_counter()
    for seed in range(repeats):
        task.evaluate(theta, seed)
        task.true_value(theta)
    per_eval = (time.perf_counter() - start) / repeats
    print(f"{name}: {per_eval:.3f} s per evaluation incl. true_value ({label}, 6 episodes)")

    rng = np.random.default_rng(1)
    thetas = rng.uniform(size=(8 * repeats, task.dim))
    start = time.perf_counter()
    lengths = []
    for k, th in enumerate(thetas):
        lengths.append(task.rollout(th, k).steps)
        task.true_value(th)
    per_eval = (time.perf_counter() - start) / len(thetas)
    print(
        f"{name}: {per_eval:.3f} s per evaluation incl. true_value (uniform random theta, "
        f"mean episode length {np.mean(lengths):.0f} steps)"
    )


def tunability(name: str, seeds: int, budget: int) -> None:
    """Best-seen true_value after 2 and after ``budget`` uniform random evaluations."""
    task = make_task(name)
    first, last = [], []
    for seed in range(seeds):
        thetas = np.random.default_rng(seed).uniform(size=(budget, task.dim))
        values = np.array([task.true_value(t) for t in thetas])
        first.append(values[:2].max())
        last.append(values.max())
    print(
        f"{name}: random search best-seen true_value after 2 evals "
        f"{np.mean(first):.1f} ± {np.std(first):.1f}, after {budget} evals "
        f"{np.mean(last):.1f} ± {np.std(last):.1f} ({seeds} seeds)"
    )


def main(argv: list[str] | None = None) -> None:
    """Command-line entry point (see module docstring)."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="fewer repetitions")
    args = parser.parse_args(argv)
    repeats = 2 if args.quick else 5
    for name in ("swimmer", "hopper", "walker2d"):
        speed(name, repeats)
    tunability("swimmer", seeds=3 if args.quick else 5, budget=40)


if __name__ == "__main__":
    main()
