"""Rollouts for the judge's page: candidate k's episode re-run with its limbs recorded.

The judge re-runs the episode itself rather than having ``sim_node`` publish frames: the
episode is a pure function of the run seed, the candidate id and θ in task units
(``episode_seed(run seed, k)``, ``evaluate_native``), so the re-run is the very episode the
simulator scored (``record_native`` returns the same return, tested in ``tests/sims``); the
topics, the simulator and the bags stay as they are (no per-frame traffic for runs without a
person), and a pool worker or a bridge never has to know about a page. It costs one more
episode per candidate shown (Hopper: ~50 ms), computed on demand and cached.

Memory is bounded: one frame per ``stride`` control steps (≤ 1000 / stride + 2 frames of a few
capsules each) and at most ``max_entries`` rollouts kept (least recently used dropped).
"""

from __future__ import annotations

import threading
from collections import OrderedDict
from collections.abc import Callable
from typing import Any

import numpy as np

from localpbo_core.seeds import episode_seed
from localpbo_ros.episode_process import EpisodeProcessError

AXIS_NAMES = ("x", "y", "z")


class RolloutCache:
    """Recorded episodes of a run's candidates, as JSON-ready dicts.

    Args:
        task: the run's task (a ``localpbo_sims.LinearPolicyTask``: ``record_native``).
        run_seed: the run seed (episode seeds derive from it).
        stride: control steps between two frames.
        max_entries: rollouts kept (0 = none kept, every request re-runs the episode).
        recorder: ``(candidate id, θ) -> task.record_native(θ, episode seed, stride)``
            computed elsewhere (:class:`~localpbo_ros.episode_process.EpisodeProcess`: off
            this process's interpreter lock); when it raises
            :class:`~localpbo_ros.episode_process.EpisodeProcessError` the episode is
            recorded here.
    """

    def __init__(
        self,
        task: Any,
        run_seed: int,
        *,
        stride: int,
        max_entries: int,
        recorder: Callable[[int, tuple[float, ...]], Any] | None = None,
    ) -> None:
        self.task = task
        self.run_seed = run_seed
        self.stride = stride
        self.max_entries = max_entries
        self.recorder = recorder
        self._lock = threading.Lock()  # one MuJoCo data: one episode at a time
        # by (id, θ): the branches of a speculation propose different θ under one id
        self._cache: OrderedDict[tuple[int, tuple[float, ...]], dict[str, Any]] = OrderedDict()
        self.episodes = 0

    def get(self, candidate_id: int, native: tuple[float, ...]) -> dict[str, Any]:
        """The rollout of candidate ``candidate_id`` with θ ``native`` (task units).

        Keys: ``candidate_id``, ``dt`` (seconds per control step), ``stride``, ``axes``
        (e.g. ``["x", "z"]``), ``geoms``, ``radii``, ``steps`` (episode length),
        ``terminated``, ``frame_steps`` and ``frames`` (per frame, per capsule
        ``[u1, v1, u2, v2]``, metres rounded to 0.1 mm).
        """
        with self._lock:
            key = (candidate_id, tuple(native))
            hit = self._cache.get(key)
            if hit is not None:
                self._cache.move_to_end(key)
                return hit
            try:
                rec = None if self.recorder is None else self.recorder(candidate_id, tuple(native))
            except EpisodeProcessError:
                rec = None  # the worker is gone: record the episode here
            if rec is None:
                rec = self.task.record_native(
                    np.asarray(native, dtype=np.float64),
                    episode_seed(self.run_seed, candidate_id),
                    self.stride,
                )
            self.episodes += 1
            out = {
                "candidate_id": candidate_id,
                "dt": rec.dt,
                "stride": rec.stride,
                "axes": [AXIS_NAMES[a] for a in rec.axes],
                "geoms": list(rec.geoms),
                "radii": list(rec.radii),
                "steps": rec.episode.steps,
                "terminated": rec.episode.terminated,
                "frame_steps": list(rec.frame_steps),
                "frames": np.round(rec.frames, 4).tolist(),
            }
            if self.max_entries > 0:
                self._cache[key] = out
                while len(self._cache) > self.max_entries:
                    self._cache.popitem(last=False)
            return out

    def __len__(self) -> int:
        return len(self._cache)
