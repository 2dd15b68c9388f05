"""Lean episode runner directly on ``mujoco`` that reproduces gymnasium's v5 environments.

The runner keeps only what defines the task of gymnasium's ``Hopper-v5``, ``Walker2d-v5``,
``Swimmer-v5`` and ``InvertedPendulum-v5`` (no wrappers, no env checker, no rendering), step
for step identical to gymnasium 1.4 (checked by
``tests/sims/test_sims_runner_vs_gymnasium.py``):

* model: gymnasium's own XML asset, ``frame_skip`` physics steps per control step;
* reset: ``mj_resetData``, then ``qpos0 + U(-s, s)`` and ``0 + U(-s, s)`` drawn from
  ``numpy.random.default_rng(seed)`` (what ``env.reset(seed=seed)`` does), then ``mj_forward``;
* step: ``ctrl = action`` (MuJoCo clamps to ``ctrlrange``), ``mj_step`` x ``frame_skip``;
* observation, reward, termination exactly as in gymnasium's ``step`` (see the two step
  functions below); episodes end at termination or after ``max_steps`` steps (gymnasium's
  ``TimeLimit`` of 1000 steps).

``mj_rnePostConstraint`` (run by gymnasium after each step) only fills ``cacc``/``cfrc_*``,
which none of these observations use, so it is skipped.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Literal

import mujoco
import numpy as np

from .models import load_model

EnvKind = Literal["planar_walker", "swimmer", "inverted_pendulum"]


@dataclass(frozen=True)
class EnvSpec:
    """The parameters of one gymnasium v5 environment (defaults of its ``__init__``).

    ``healthy_reward`` is the per-step alive bonus of Hopper/Walker2d; the linear-policy tasks
    set it to 0 by default (see ``localpbo_sims.tasks``). ``healthy_state_range`` is ``None``
    for Walker2d, which has no state-range health check.
    """

    env_id: str
    xml_file: str
    frame_skip: int
    reset_noise_scale: float
    kind: EnvKind
    forward_reward_weight: float = 1.0
    ctrl_cost_weight: float = 1e-3
    healthy_reward: float = 1.0
    healthy_z_range: tuple[float, float] = (-np.inf, np.inf)
    healthy_angle_range: tuple[float, float] = (-np.inf, np.inf)
    healthy_state_range: tuple[float, float] | None = None


HOPPER_V5 = EnvSpec(
    env_id="Hopper-v5",
    xml_file="hopper.xml",
    frame_skip=4,
    reset_noise_scale=5e-3,
    kind="planar_walker",
    healthy_z_range=(0.7, np.inf),
    healthy_angle_range=(-0.2, 0.2),
    healthy_state_range=(-100.0, 100.0),
)

WALKER2D_V5 = EnvSpec(
    env_id="Walker2d-v5",
    xml_file="walker2d_v5.xml",
    frame_skip=4,
    reset_noise_scale=5e-3,
    kind="planar_walker",
    healthy_z_range=(0.8, 2.0),
    healthy_angle_range=(-1.0, 1.0),
    healthy_state_range=None,
)

SWIMMER_V5 = EnvSpec(
    env_id="Swimmer-v5",
    xml_file="swimmer.xml",
    frame_skip=4,
    reset_noise_scale=0.1,
    kind="swimmer",
    ctrl_cost_weight=1e-4,
    healthy_reward=0.0,
)

INVERTED_PENDULUM_V5 = EnvSpec(
    env_id="InvertedPendulum-v5",
    xml_file="inverted_pendulum.xml",
    frame_skip=2,
    reset_noise_scale=0.01,
    kind="inverted_pendulum",
)


@dataclass(frozen=True)
class EpisodeResult:
    """Outcome of one episode: summed reward, number of steps, and whether it terminated."""

    episode_return: float
    steps: int
    terminated: bool


PLANES: dict[EnvKind, tuple[int, int]] = {
    "planar_walker": (0, 2),
    "swimmer": (0, 1),
    "inverted_pendulum": (0, 2),
}
"""The world axes each kind of model moves in (Hopper/Walker2d: x/z; Swimmer: x/y)."""


@dataclass(frozen=True)
class Recording:
    """An episode with the positions of its bodies, for drawing it in 2-D.

    Every capsule geom of the model (the limbs) is a segment ``(u1, v1, u2, v2)`` in the plane
    the model moves in (``axes``, world axes: 0 = x, 1 = y, 2 = z) with radius ``radii[i]``.
    Frame 0 is the state after reset; then one frame every ``stride`` control steps and always
    the last step, so ``frame_steps`` (control steps since reset) ends at ``episode.steps``.

    Attributes:
        episode: the episode's return and length (identical to the plain episode's).
        dt: seconds per control step.
        stride: control steps between two frames.
        axes: the two world axes of the segments.
        geoms: the capsules' names (``geom<i>`` for unnamed ones).
        radii: the capsules' radii.
        frame_steps: control step of each frame.
        frames: ``(n_frames, n_capsules, 4)`` segment end points.
    """

    episode: EpisodeResult
    dt: float
    stride: int
    axes: tuple[int, int]
    geoms: tuple[str, ...]
    radii: tuple[float, ...]
    frame_steps: tuple[int, ...]
    frames: np.ndarray


class EpisodeRunner:
    """Runs episodes of one environment on a private ``MjModel``/``MjData`` pair.

    Not thread-safe (one ``MjData``); create one runner per thread.
    """

    def __init__(self, spec: EnvSpec) -> None:
        self.spec = spec
        self.model = load_model(spec.xml_file)
        self.data = mujoco.MjData(self.model)
        self.init_qpos = self.data.qpos.copy()
        self.init_qvel = self.data.qvel.copy()
        self.dt = float(self.model.opt.timestep) * spec.frame_skip
        self.action_dim = int(self.model.nu)
        self.obs_dim = int(self.observation().size)

    def observation(self) -> np.ndarray:
        """The environment's observation of the current state (gymnasium ``_get_obs``)."""
        qpos, qvel = self.data.qpos, self.data.qvel
        if self.spec.kind == "planar_walker":
            return np.concatenate((qpos[1:], np.clip(qvel, -10.0, 10.0)))
        if self.spec.kind == "swimmer":
            return np.concatenate((qpos[2:], qvel))
        return np.concatenate((qpos, qvel))

    def reset(self, seed: int) -> np.ndarray:
        """Reset with reset noise drawn from ``default_rng(seed)``; return the observation."""
        rng = np.random.default_rng(seed)
        scale = self.spec.reset_noise_scale
        mujoco.mj_resetData(self.model, self.data)
        qpos = self.init_qpos + rng.uniform(low=-scale, high=scale, size=self.model.nq)
        qvel = self.init_qvel + rng.uniform(low=-scale, high=scale, size=self.model.nv)
        self.data.qpos[:] = qpos
        self.data.qvel[:] = qvel
        mujoco.mj_forward(self.model, self.data)
        return self.observation()

    def _is_healthy(self) -> bool:
        spec, qpos = self.spec, self.data.qpos
        z, angle = qpos[1], qpos[2]
        if not (spec.healthy_z_range[0] < z < spec.healthy_z_range[1]):
            return False
        if not (spec.healthy_angle_range[0] < angle < spec.healthy_angle_range[1]):
            return False
        if spec.healthy_state_range is not None:
            low, high = spec.healthy_state_range
            state = np.concatenate((qpos[2:], self.data.qvel))
            if not bool(np.all((low < state) & (state < high))):
                return False
        return True

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool]:
        """One control step; returns ``(observation, reward, terminated)`` as gymnasium does.

        Hopper/Walker2d: ``r = w_f * (x_after - x_before) / dt + healthy * b - c * |a|^2``
        with ``b`` the alive bonus, terminated when unhealthy. Swimmer: the same without alive
        bonus and without termination (``c = 1e-4``). InvertedPendulum: ``r = 1`` while
        the observation is finite and ``|hinge angle| <= 0.2``, else ``r = 0`` and terminated.
        """
        spec, data = self.spec, self.data
        if spec.kind == "swimmer":
            x_before = float(data.qpos[0])
            data.ctrl[:] = action
            mujoco.mj_step(self.model, data, nstep=spec.frame_skip)
            x_velocity = (float(data.qpos[0]) - x_before) / self.dt
            reward = spec.forward_reward_weight * x_velocity - spec.ctrl_cost_weight * float(
                np.sum(np.square(action))
            )
            return self.observation(), reward, False
        if spec.kind == "planar_walker":
            x_before = float(data.qpos[0])
            data.ctrl[:] = action
            mujoco.mj_step(self.model, data, nstep=spec.frame_skip)
            x_velocity = (float(data.qpos[0]) - x_before) / self.dt
            obs = self.observation()
            healthy = self._is_healthy()
            reward = (
                spec.forward_reward_weight * x_velocity
                + healthy * spec.healthy_reward
                - spec.ctrl_cost_weight * float(np.sum(np.square(action)))
            )
            return obs, reward, not healthy
        data.ctrl[:] = action
        mujoco.mj_step(self.model, data, nstep=spec.frame_skip)
        obs = self.observation()
        terminated = bool(not np.isfinite(obs).all() or abs(obs[1]) > 0.2)
        return obs, float(not terminated), terminated

    def run_linear(
        self,
        weights: np.ndarray,
        obs_mean: np.ndarray,
        obs_std: np.ndarray,
        seed: int,
        max_steps: int = 1000,
    ) -> EpisodeResult:
        """One episode of the linear policy ``a = weights @ ((obs - obs_mean) / obs_std)``.

        The policy of ARS (Mania et al. 2018), used by the paper's policy-search tasks
        (Sec. 6 "Policy Search", App. D.6 "Policy-Search"); no bias and no action clipping
        beyond MuJoCo's ``ctrlrange`` clamp (the control cost uses the unclipped action, as in
        gymnasium).
        """
        return self._linear_episode(weights, obs_mean, obs_std, seed, max_steps, None)

    def _linear_episode(
        self,
        weights: np.ndarray,
        obs_mean: np.ndarray,
        obs_std: np.ndarray,
        seed: int,
        max_steps: int,
        on_step: Callable[[int, bool], None] | None,
    ) -> EpisodeResult:
        """The episode loop of :meth:`run_linear`; ``on_step(step, last)`` after reset (step
        0) and after every control step."""
        obs = self.reset(seed)
        if on_step is not None:
            on_step(0, False)
        total = 0.0
        for step in range(1, max_steps + 1):
            action = weights @ ((obs - obs_mean) / obs_std)
            obs, reward, terminated = self.step(action)
            total += reward
            if on_step is not None:
                on_step(step, terminated or step == max_steps)
            if terminated:
                return EpisodeResult(total, step, True)
        return EpisodeResult(total, max_steps, False)

    def observation_names(self) -> tuple[str, ...]:
        """One label per observation entry: ``<joint>.pos`` / ``<joint>.vel`` (these models
        have one-dimensional joints only, so qpos/qvel entry i belongs to joint i)."""
        joints = [self.model.joint(i).name for i in range(self.model.njnt)]
        skip = {"planar_walker": 1, "swimmer": 2, "inverted_pendulum": 0}[self.spec.kind]
        return tuple(f"{j}.pos" for j in joints[skip:]) + tuple(f"{j}.vel" for j in joints)

    def actuator_names(self) -> tuple[str, ...]:
        """One label per action entry: the joint each actuator drives."""
        trn = self.model.actuator_trnid[:, 0]
        return tuple(self.model.joint(int(j)).name or f"a{i}" for i, j in enumerate(trn))

    def capsules(self) -> tuple[np.ndarray, tuple[str, ...]]:
        """Indices and names of the model's capsule geoms (the drawn limbs)."""
        ids = np.flatnonzero(self.model.geom_type == mujoco.mjtGeom.mjGEOM_CAPSULE)
        names = tuple(self.model.geom(int(i)).name or f"geom{int(i)}" for i in ids)
        return ids, names

    def segments(self, ids: np.ndarray) -> np.ndarray:
        """``(len(ids), 4)`` end points of the capsules ``ids`` in the model's plane now: the
        geom centre ± half-length along the capsule's axis (the local z axis)."""
        u, v = PLANES[self.spec.kind]
        centre = self.data.geom_xpos[ids]
        axis = self.data.geom_xmat[ids].reshape(-1, 3, 3)[:, :, 2]
        half = self.model.geom_size[ids, 1][:, None] * axis
        a, b = centre - half, centre + half
        return np.stack((a[:, u], a[:, v], b[:, u], b[:, v]), axis=1)

    def record_linear(
        self,
        weights: np.ndarray,
        obs_mean: np.ndarray,
        obs_std: np.ndarray,
        seed: int,
        max_steps: int = 1000,
        stride: int = 4,
    ) -> Recording:
        """:meth:`run_linear` (the same episode, step for step) recording the limbs every
        ``stride`` control steps (see :class:`Recording`); memory is
        ``O(max_steps / stride × capsules)``."""
        if isinstance(stride, bool) or not isinstance(stride, int) or stride < 1:
            raise ValueError(f"stride: expected a positive integer, got {stride!r}")
        ids, names = self.capsules()
        frames: list[np.ndarray] = []
        steps: list[int] = []

        def on_step(step: int, last: bool) -> None:
            if step % stride == 0 or last:
                frames.append(self.segments(ids))
                steps.append(step)

        episode = self._linear_episode(weights, obs_mean, obs_std, seed, max_steps, on_step)
        return Recording(
            episode,
            self.dt,
            stride,
            PLANES[self.spec.kind],
            names,
            tuple(float(r) for r in self.model.geom_size[ids, 0]),
            tuple(steps),
            np.asarray(frames, dtype=np.float64).reshape(len(frames), len(ids), 4),
        )
