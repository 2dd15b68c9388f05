"""A PID position loop on a mass-spring-damper, plain Python (no ROS), deterministic per seed.

Plant: ``m ẍ = u − c ẋ − k x`` (semi-implicit Euler, step ``dt``), actuator limited to
``|u| <= u_max``, position measured with Gaussian noise (std ``noise_std``, drawn from the
episode's seed). Controller: ``u = kp e + ki ∫e − kd d(y)/dt`` with ``e = setpoint − y``
(derivative on the measurement, so a setpoint step gives no kick; the integral is clamped
while the actuator saturates). Cost per step: ``(e² + effort_weight u²) dt``; an episode is a
step response of ``episode_steps`` steps from rest, and its cost is the sum.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class PlantConfig:
    """The simulated system and the episode."""

    mass: float = 1.0
    damping: float = 0.2
    stiffness: float = 1.0
    u_max: float = 20.0
    dt: float = 0.01
    setpoint: float = 1.0
    noise_std: float = 0.01
    effort_weight: float = 0.001
    episode_steps: int = 300


class PidLoop:
    """One episode of the closed loop; :meth:`step` advances one control step.

    Args:
        config: plant and episode.
        seed: seeds the measurement noise (same seed and gains ⇒ same costs).
    """

    def __init__(self, config: PlantConfig, seed: int = 0) -> None:
        self.config = config
        self.reset(seed)

    def reset(self, seed: int) -> None:
        """Back to rest at x = 0 with a fresh noise stream from ``seed``."""
        self._rng = np.random.default_rng(seed)
        self.x = 0.0
        self.v = 0.0
        self.integral = 0.0
        self.previous_y: float | None = None
        self.steps = 0

    def stop(self) -> None:
        """End the episode now (the loop then waits for :meth:`reset`)."""
        self.steps = self.config.episode_steps

    @property
    def done(self) -> bool:
        """The episode's steps are used up."""
        return self.steps >= self.config.episode_steps

    def step(self, kp: float, ki: float, kd: float) -> float:
        """One control step with these gains; returns its cost."""
        c = self.config
        y = self.x + c.noise_std * float(self._rng.standard_normal())
        e = c.setpoint - y
        dy = 0.0 if self.previous_y is None else (y - self.previous_y) / c.dt
        self.previous_y = y
        raw = kp * e + ki * (self.integral + e * c.dt) - kd * dy
        u = min(max(raw, -c.u_max), c.u_max)
        if u == raw:  # anti-windup: integrate only while the actuator is not saturated
            self.integral += e * c.dt
        a = (u - c.damping * self.v - c.stiffness * self.x) / c.mass
        self.v += a * c.dt
        self.x += self.v * c.dt
        self.steps += 1
        return (e * e + c.effort_weight * u * u) * c.dt


def episode_cost(kp: float, ki: float, kd: float, config: PlantConfig, seed: int = 0) -> float:
    """The cost of one whole episode with fixed gains (what a trial measures)."""
    loop = PidLoop(config, seed)
    total = 0.0
    while not loop.done:
        total += loop.step(kp, ki, kd)
    return total
