"""Recorded episodes (``record_native``): the same episode as ``evaluate_native``, with the
limbs' segments every ``stride`` steps, bounded in size."""

from __future__ import annotations

import numpy as np
import pytest
from localpbo_sims import ArsPolicy, load_ars_policy, make_task


def _ars_native(name: str) -> np.ndarray:
    """The published ARS policy (a long, healthy episode) clipped into the task box."""
    task = make_task(name)
    ars: ArsPolicy = load_ars_policy(name)
    return task.to_native(task.theta_from_weights(ars.weights).theta)


@pytest.mark.parametrize(("name", "seed"), [("hopper", 3), ("walker2d", 11)])
def test_recording_has_the_plain_episodes_return(name: str, seed: int) -> None:
    task = make_task(name)
    x = _ars_native(name)
    rec = task.record_native(x, seed, stride=5)
    assert rec.episode.episode_return == task.evaluate_native(x, seed)  # bit for bit
    assert rec.episode == task.rollout_weights(x.reshape(task.action_dim, task.obs_dim), seed)
    steps = rec.episode.steps
    assert rec.frame_steps[0] == 0 and rec.frame_steps[-1] == steps
    assert all(s % 5 == 0 for s in rec.frame_steps[:-1])
    assert rec.frames.shape == (len(rec.frame_steps), len(rec.geoms), 4)
    assert np.all(np.isfinite(rec.frames))
    assert rec.axes == (0, 2) and rec.dt == pytest.approx(0.008)


def test_hopper_segments_follow_the_body() -> None:
    task = make_task("hopper")
    rec = task.record_native(_ars_native("hopper"), 3, stride=10)
    assert rec.geoms == ("torso_geom", "thigh_geom", "leg_geom", "foot_geom")
    assert rec.radii == pytest.approx((0.05, 0.05, 0.04, 0.06))
    first = rec.frames[0]
    # standing after reset: torso from z 1.05 to 1.45, foot on the floor (z 0.1)
    torso = first[0]
    assert sorted((torso[1], torso[3])) == pytest.approx([1.05, 1.45], abs=0.02)
    assert first[3][1] == pytest.approx(0.1, abs=0.02) and first[3][3] == pytest.approx(
        0.1, abs=0.02
    )
    # the ARS policy hops forward: the torso's x grows over the episode
    assert rec.frames[-1][0][0] > first[0][0] + 1.0
    # limb lengths are rigid: each segment keeps its length in every frame
    lengths = np.hypot(
        rec.frames[..., 2] - rec.frames[..., 0], rec.frames[..., 3] - rec.frames[..., 1]
    )
    assert np.allclose(lengths, lengths[0], atol=1e-9)


def test_swimmer_moves_in_the_xy_plane_and_stride_bounds_the_size() -> None:
    task = make_task("swimmer", episode_steps=100)
    x = task.to_native(np.full(task.dim, 0.7))
    dense = task.record_native(x, 0, stride=1)
    sparse = task.record_native(x, 0, stride=30)
    assert dense.axes == (0, 1)
    assert dense.episode == sparse.episode and dense.episode.steps == 100
    assert dense.frame_steps == tuple(range(101))
    assert sparse.frame_steps == (0, 30, 60, 90, 100)
    assert np.array_equal(sparse.frames, dense.frames[list(sparse.frame_steps)])


@pytest.mark.parametrize("stride", [0, -1, 2.5, True])
def test_bad_stride_refused(stride: object) -> None:
    task = make_task("swimmer", episode_steps=10)
    with pytest.raises(ValueError, match="stride"):
        task.record_native(np.zeros(task.dim), 0, stride=stride)  # type: ignore[arg-type]


def test_parameter_names_follow_the_weight_layout() -> None:
    task = make_task("hopper")
    names = task.parameter_names()
    assert len(names) == task.dim == len(set(names))
    assert names[0] == "W[thigh_joint, rootz.pos]"
    assert names[task.obs_dim] == "W[leg_joint, rootz.pos]"  # row-major: action 1 starts
    assert names[-1] == "W[foot_joint, foot_joint.vel]"
