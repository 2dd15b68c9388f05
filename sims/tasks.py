"""Linear-policy tasks on gymnasium v5 MuJoCo models (paper Sec. 6, App. D.6 "Policy-Search").

A task is a maximisation problem on theta in [0,1]^d that satisfies ``localpbo_core``'s
``Problem`` protocol structurally (this package does not import ``localpbo_core``):

* Tasks: ``hopper`` (Hopper-v5, 11 obs x 3 actions = 33-D), ``walker2d`` (Walker2d-v5,
  17 x 6 = 102-D) and the small demo task ``swimmer`` (Swimmer-v5, 8 x 2 = 16-D; never
  terminates, so every episode has 1000 steps; random policies score about -3 median, the
  best of 40 random ones about 100-180, good linear policies about 350).
* Policy (ARS, Mania et al. 2018, as in the paper): ``a = W @ ((obs - mean) / std)``, no bias,
  ``W`` of shape (actions, observations), ``d = actions * observations``.
* Box: theta maps affinely onto ``W`` in ``[weight_low, weight_high]^d`` = ``[-1, 1]^d`` by
  default, ``W.ravel() = weight_low + (weight_high - weight_low) * theta`` (row-major:
  the weights of action 0 first). ``around_ars = r`` (Hopper, Walker2d) centres the box on
  the published ARS policy instead: ``W_ars ± r`` per weight (unclipped), so θ = 0.5 is that
  policy and every θ a perturbation of it; the episodes last long enough to be watched (on
  Hopper with ``r = 0.1``: 0.6–8 s, against 0.05–0.14 s for most points of the default box).
  ``ARS_RADII`` holds the radius ``localpbo run --oracle human`` uses.
* Goal: ``GOALS`` (and ``LinearPolicyTask.goal``) says in one line what "better" means for a
  person judging two episodes.
* Observation normalisation: fixed ARS statistics (``data/ars/``) for Hopper and Walker2d;
  identity (mean 0, std 1) for Swimmer, which has no ARS data here.
* Reward: gymnasium's v5 reward. **Alive bonus removed by default** (``alive_bonus=False``
  sets ``healthy_reward = 0``; the return is forward progress minus control cost, what ARS's
  ``shift`` does), as suggested by the paper's negative cumulative sums for Walker2d Sobol.
  Measured here (``python -m localpbo_core.problems.calibrate --problem P --sobol-seeds ...``),
  Sobol best-seen ``true_value`` after 15d evaluations: Hopper 159 ± 53 (10 seeds; paper
  360 ± 239), Walker2d 143 ± 47 (5 seeds; paper 113 ± 39). With the alive bonus kept the
  same runs give about 1000 (Hopper) and 800 (Walker2d), far above the paper.
* ``evaluate(theta, seed)``: one 1000-step episode (ends early on termination) whose reset
  noise comes from ``seed`` — the value a real experiment would produce.
* ``true_value(theta)``: the noise-free value used for reporting, the mean return over the
  fixed reset seeds ``TRUE_VALUE_SEEDS`` (5 episodes); cached per theta.
* ``value_range``: the spread between the 1st and 99th percentiles of ``true_value`` over the
  first 256 points of a scrambled Sobol sequence (scipy ``qmc.Sobol(d, scramble=True,
  seed=0)``), computed offline by ``python -m localpbo_core.problems.calibrate --problem NAME
  --points 256 --quantiles 1,99`` and stored in ``VALUE_RANGES``; the oracle's noise std is a
  fraction of it (paper Sec. 6 and eq. (2) "observation noise"). Not max − min: the returns
  of random linear policies are heavy-tailed (on Walker2d one return of −1438 alone sets
  max − min to 1592, eight times the percentile spread), and at 10 % of such a range the duels
  between ordinary policies are coin flips. Runs recorded when max − min was the definition
  (``MAX_MIN_VALUE_RANGES``) name no value range in their run config and are replayed with it
  (``recorded_value_range``).
"""

from __future__ import annotations

from collections import OrderedDict
from dataclasses import dataclass
from typing import NamedTuple, TypedDict, Unpack

import numpy as np

from . import episode
from .ars import load_ars_policy

TRUE_VALUE_SEEDS: tuple[int, ...] = (1_000_003, 1_000_033, 1_000_037, 1_000_039, 1_000_081)
"""Reset seeds whose mean return defines ``true_value`` (fixed for every task and run)."""

EPISODE_STEPS = 1000
"""Episode length (gymnasium's ``TimeLimit`` for these environments)."""

VALUE_RANGES: dict[str, float] = {
    "hopper": 106.44871095637265,
    "walker2d": 197.1365737538254,
    "swimmer": 342.0488324301364,
}
"""The 1st–99th percentile spread of ``true_value`` over 256 scrambled Sobol points (seed 0),
alive bonus removed: the default noise scale.

Reproduce with ``python -m localpbo_core.problems.calibrate --problem NAME --points 256
--quantiles 1,99``.
"""

MAX_MIN_VALUE_RANGES: dict[str, float] = {
    "hopper": 207.1290855685183,
    "walker2d": 1591.9755705939224,
    "swimmer": 444.35762252828846,
}
"""max − min of the same values: the default noise scale of runs recorded before
``VALUE_RANGES`` (their run configs name no value range; see :func:`recorded_value_range`).

Reproduce with ``python -m localpbo_core.problems.calibrate --problem NAME --points 256``.
"""


GOALS: dict[str, str] = {
    "hopper": "Better = hops farther forward (to the right) without falling, with less effort.",
    "walker2d": "Better = walks farther forward (to the right) without falling, with less effort.",
    "swimmer": "Better = swims farther forward (to the right) in the same time, with less effort.",
}
"""What "better" means for each task, in the words of its reward (forward progress minus the
control cost), for the person who judges duels of its episodes."""

ARS_RADII: dict[str, float] = {"hopper": 0.1, "walker2d": 0.05}
"""The ``around_ars`` radius (weight units) a person's run uses by default: perturbations of
the ARS policy whose episodes mostly last long enough to be judged (measured on 12 random
perturbations each: Hopper 0.1 gives 80–1000 steps, returns 81–2804; Walker2d 0.05 gives
15–1000 steps, a third of them shorter than 0.2 s, and a wider radius makes most fall at once).
"""


class ThetaFromWeights(NamedTuple):
    """Result of mapping weights into the unit cube: ``theta`` and which entries were clipped."""

    theta: np.ndarray
    clipped: np.ndarray

    @property
    def n_clipped(self) -> int:
        """How many weights lay outside the box and were clipped to its boundary."""
        return int(np.count_nonzero(self.clipped))


@dataclass(frozen=True)
class _TaskConfig:
    name: str
    spec: episode.EnvSpec
    ars_task: str | None


_TASKS: dict[str, _TaskConfig] = {
    "hopper": _TaskConfig("hopper", episode.HOPPER_V5, "hopper"),
    "walker2d": _TaskConfig("walker2d", episode.WALKER2D_V5, "walker2d"),
    "swimmer": _TaskConfig("swimmer", episode.SWIMMER_V5, None),
}


def available_tasks() -> list[str]:
    """Names of the linear-policy tasks (``hopper``, ``swimmer``, ``walker2d``)."""
    return sorted(_TASKS)


def _check_seed(seed: int) -> int:
    """The seed as a Python int >= 0 (the wording of ``localpbo_core.validation.check_int``;
    this package does not import ``localpbo_core``)."""
    if isinstance(seed, bool) or not isinstance(seed, int | np.integer) or seed < 0:
        raise ValueError(f"seed: must be an integer >= 0, got {seed!r}")
    return int(seed)


class LinearPolicyTask:
    """A linear-policy MuJoCo task on theta in [0,1]^d (see the module docstring).

    Args:
        name: ``"hopper"`` (33-D), ``"walker2d"`` (102-D) or ``"swimmer"`` (16-D, fast demo).
        alive_bonus: keep gymnasium's alive bonus (1 per healthy step) in the return;
            default ``False`` (removed, see module docstring). Only affects Hopper/Walker2d.
        weight_low, weight_high: the weight box that theta maps onto (default [-1, 1]).
        episode_steps: maximum steps per episode (default 1000).
        cache_size: number of ``true_value`` results kept (0 disables the cache).
        value_range: override of the stored value range (needed by the oracle when the task
            definition differs from the calibrated default: other box, alive bonus kept,
            other episode length; those otherwise get ``nan``).
        around_ars: the box ``W_ars ± around_ars`` per weight around the task's ARS policy
            instead of ``[weight_low, weight_high]`` (which must then keep their defaults).

    Attributes:
        calibrated: the options keep the definition ``VALUE_RANGES`` was calibrated for.
    """

    def __init__(
        self,
        name: str,
        *,
        alive_bonus: bool = False,
        weight_low: float = -1.0,
        weight_high: float = 1.0,
        episode_steps: int = EPISODE_STEPS,
        cache_size: int = 4096,
        value_range: float | None = None,
        around_ars: float | None = None,
    ) -> None:
        if not isinstance(name, str) or name not in _TASKS:
            raise ValueError(
                f"name: unknown linear-policy task {name!r}; valid: {available_tasks()}"
            )
        for label, bound in (("weight_low", weight_low), ("weight_high", weight_high)):
            if isinstance(bound, bool) or not isinstance(bound, int | float | np.floating):
                raise ValueError(f"{label}: expected a number, got {bound!r}")
        if not (np.isfinite(weight_low) and np.isfinite(weight_high) and weight_low < weight_high):
            raise ValueError(
                f"weight_low/weight_high: need finite weight_low < weight_high, "
                f"got {weight_low!r}, {weight_high!r}"
            )
        if not isinstance(episode_steps, int) or isinstance(episode_steps, bool):
            raise ValueError(f"episode_steps: expected a positive integer, got {episode_steps!r}")
        if episode_steps < 1:
            raise ValueError(f"episode_steps: expected a positive integer, got {episode_steps!r}")
        if value_range is not None and not (np.isfinite(value_range) and value_range > 0):
            raise ValueError(f"value_range: expected a positive finite number, got {value_range!r}")
        if isinstance(cache_size, bool) or not isinstance(cache_size, int) or cache_size < 0:
            raise ValueError(f"cache_size: expected a non-negative integer, got {cache_size!r}")
        if not isinstance(alive_bonus, bool):
            raise ValueError(f"alive_bonus: expected a bool, got {alive_bonus!r}")
        config = _TASKS[name]
        low: float | np.ndarray = float(weight_low)
        high: float | np.ndarray = float(weight_high)
        if around_ars is not None:
            if isinstance(around_ars, bool) or not isinstance(around_ars, int | float):
                raise ValueError(f"around_ars: expected a number, got {around_ars!r}")
            if not (np.isfinite(around_ars) and around_ars > 0):
                raise ValueError(f"around_ars: expected a positive radius, got {around_ars!r}")
            if config.ars_task is None:
                raise ValueError(
                    f"around_ars: {name} has no ARS policy; valid for hopper, walker2d"
                )
            if (low, high) != (-1.0, 1.0):
                raise ValueError("around_ars: weight_low/weight_high must keep their defaults")
            centre = load_ars_policy(config.ars_task).weights.ravel()
            low, high = centre - float(around_ars), centre + float(around_ars)
        self.around_ars = None if around_ars is None else float(around_ars)
        spec = config.spec
        if spec.kind == "planar_walker" and not alive_bonus:
            spec = episode.EnvSpec(**{**spec.__dict__, "healthy_reward": 0.0})
        self.name = name
        self.alive_bonus = alive_bonus
        self.spec = spec
        self.weight_low = low
        self.weight_high = high
        self.goal = GOALS[name]
        self.episode_steps = episode_steps
        self._runner = episode.EpisodeRunner(spec)
        self.obs_dim = self._runner.obs_dim
        self.action_dim = self._runner.action_dim
        self.dim = self.obs_dim * self.action_dim
        if config.ars_task is not None:
            ars = load_ars_policy(config.ars_task)
            self.obs_mean, self.obs_std = ars.obs_mean, ars.obs_std
        else:
            self.obs_mean, self.obs_std = np.zeros(self.obs_dim), np.ones(self.obs_dim)
        same_definition = (
            calibrated_definition(
                name,
                alive_bonus=alive_bonus,
                weight_low=weight_low,
                weight_high=weight_high,
                episode_steps=episode_steps,
            )
            and around_ars is None
        )
        if value_range is not None:
            self.value_range = float(value_range)
        else:
            self.value_range = VALUE_RANGES[name] if same_definition else float("nan")
        self.calibrated = same_definition
        self._cache: OrderedDict[bytes, float] = OrderedDict()
        self._cache_size = int(cache_size)

    def __repr__(self) -> str:
        box = (
            f"around_ars={self.around_ars}"
            if self.around_ars is not None
            else f"box=[{self.weight_low}, {self.weight_high}]"
        )
        return (
            f"LinearPolicyTask({self.name!r}, dim={self.dim}, alive_bonus={self.alive_bonus}, "
            f"{box})"
        )

    # -- theta <-> weights -------------------------------------------------------------
    def _check_theta(self, theta: np.ndarray) -> np.ndarray:
        """Theta as float64 ``(d,)`` in [0,1]^d (the wording of
        ``localpbo_core.validation.check_theta``)."""
        arr = np.asarray(theta, dtype=np.float64)
        if arr.shape != (self.dim,):
            raise ValueError(f"theta: expected shape ({self.dim},), got {arr.shape}")
        if not np.all(np.isfinite(arr)):
            raise ValueError("theta: contains NaN or inf")
        if np.any(arr < 0.0) or np.any(arr > 1.0):
            raise ValueError(f"theta: must lie in [0, 1]^{self.dim}")
        return arr

    def to_native(self, theta: np.ndarray) -> np.ndarray:
        """Flattened weights ``W.ravel()`` (row-major) of theta: ``low + (high - low) * theta``."""
        arr = self._check_theta(theta)
        return self.weight_low + (self.weight_high - self.weight_low) * arr

    def policy_from_theta(self, theta: np.ndarray) -> np.ndarray:
        """The weight matrix ``W`` (actions x observations) of theta."""
        return self.to_native(theta).reshape(self.action_dim, self.obs_dim)

    def theta_from_weights(self, weights: np.ndarray) -> ThetaFromWeights:
        """Map a weight matrix (or its row-major flattening) into [0,1]^d.

        Weights outside the box are clipped to its boundary; ``clipped`` marks them
        (flattened order), so a warm start from an existing controller can report it.
        """
        arr = np.asarray(weights, dtype=np.float64)
        if arr.shape not in ((self.action_dim, self.obs_dim), (self.dim,)):
            raise ValueError(
                f"weights: expected shape ({self.action_dim}, {self.obs_dim}) or ({self.dim},) "
                f"for {self.name}, got {arr.shape}"
            )
        flat = arr.ravel()
        if not np.all(np.isfinite(flat)):
            raise ValueError(f"weights: contains NaN or inf for {self.name}")
        clipped = (flat < self.weight_low) | (flat > self.weight_high)
        theta = (np.clip(flat, self.weight_low, self.weight_high) - self.weight_low) / (
            self.weight_high - self.weight_low
        )
        return ThetaFromWeights(np.clip(theta, 0.0, 1.0), clipped)

    # -- episodes ----------------------------------------------------------------------
    def rollout_weights(self, weights: np.ndarray, seed: int) -> episode.EpisodeResult:
        """One episode of an arbitrary weight matrix (not restricted to the box)."""
        w = np.asarray(weights, dtype=np.float64)
        if w.shape != (self.action_dim, self.obs_dim):
            raise ValueError(
                f"weights: expected shape ({self.action_dim}, {self.obs_dim}), got {w.shape}"
            )
        return self._runner.run_linear(
            w, self.obs_mean, self.obs_std, _check_seed(seed), self.episode_steps
        )

    def rollout(self, theta: np.ndarray, seed: int) -> episode.EpisodeResult:
        """One episode of theta's policy with reset noise from ``seed`` (return, steps, ...)."""
        return self.rollout_weights(self.policy_from_theta(theta), seed)

    def evaluate(self, theta: np.ndarray, seed: int) -> float:
        """Return of one episode of theta's policy; ``seed`` fixes the reset noise."""
        return self.rollout(theta, seed).episode_return

    def _weights_of(self, x: np.ndarray) -> np.ndarray:
        """``W`` of flattened weights ``x``; ValueError unless finite and in the box."""
        flat = np.asarray(x, dtype=np.float64)
        if flat.shape != (self.dim,):
            raise ValueError(f"x: expected shape ({self.dim},) for {self.name}, got {flat.shape}")
        if (
            not np.all(np.isfinite(flat))
            or np.any(flat < self.weight_low)
            or np.any(flat > self.weight_high)
        ):
            box = (
                f"W_ars ± {self.around_ars}"
                if self.around_ars is not None
                else f"[{self.weight_low}, {self.weight_high}]"
            )
            raise ValueError(f"x: weights must be finite and in {box} for {self.name}")
        return flat.reshape(self.action_dim, self.obs_dim)

    def evaluate_native(self, x: np.ndarray, seed: int) -> float:
        """Return of one episode of the policy with flattened weights ``x`` (in the box)."""
        weights = self._weights_of(x)
        return self.rollout_weights(weights, seed).episode_return

    def record_native(self, x: np.ndarray, seed: int, stride: int = 4) -> episode.Recording:
        """The episode of :meth:`evaluate_native` (same return) with the limbs' positions
        every ``stride`` control steps (:meth:`EpisodeRunner.record_linear`), for replaying
        it; ``x`` must lie in the box as for :meth:`evaluate_native`."""
        weights = self._weights_of(x)
        return self._runner.record_linear(
            weights, self.obs_mean, self.obs_std, _check_seed(seed), self.episode_steps, stride
        )

    def parameter_names(self) -> tuple[str, ...]:
        """Names of θ's coordinates in ``W.ravel()`` order: ``W[<actuated joint>, <observed
        entry>]``, e.g. ``W[thigh_joint, rootz.pos]``."""
        runner = self._runner
        observed = runner.observation_names()
        assert len(observed) == self.obs_dim
        return tuple(f"W[{a}, {o}]" for a in runner.actuator_names() for o in observed)

    def true_value(self, theta: np.ndarray) -> float:
        """Noise-free value: mean return over the reset seeds ``TRUE_VALUE_SEEDS``."""
        weights = self.policy_from_theta(theta)
        key = weights.tobytes()
        if key in self._cache:
            self._cache.move_to_end(key)
            return self._cache[key]
        value = float(
            np.mean([self.rollout_weights(weights, s).episode_return for s in TRUE_VALUE_SEEDS])
        )
        if self._cache_size > 0:
            self._cache[key] = value
            if len(self._cache) > self._cache_size:
                self._cache.popitem(last=False)
        return value


class TaskOptions(TypedDict, total=False):
    """The keyword options of :class:`LinearPolicyTask` (all optional)."""

    alive_bonus: bool
    weight_low: float
    weight_high: float
    episode_steps: int
    cache_size: int
    value_range: float | None
    around_ars: float | None


def recorded_value_range(name: str, **options: Unpack[TaskOptions]) -> float:
    """The value range of a run recorded without one: ``MAX_MIN_VALUE_RANGES[name]`` when the
    options keep the calibrated definition (box [-1, 1], no alive bonus, 1000 steps), else NaN
    (such a run needed an explicit value range for a noisy oracle then as now)."""
    return MAX_MIN_VALUE_RANGES[name] if calibrated_definition(name, **options) else float("nan")


def calibrated_definition(
    name: str,
    *,
    alive_bonus: bool = False,
    weight_low: float = -1.0,
    weight_high: float = 1.0,
    episode_steps: int = EPISODE_STEPS,
    around_ars: float | None = None,
    **_: object,
) -> bool:
    """Whether the task ``name`` with these options is the one ``VALUE_RANGES`` was calibrated
    for: box [-1, 1], 1000-step episodes, and no alive bonus where the task has one."""
    bonus_changed = alive_bonus and _TASKS[name].spec.kind == "planar_walker"
    default_box = (float(weight_low), float(weight_high)) == (-1.0, 1.0)
    centred = around_ars is not None
    return default_box and not centred and not bonus_changed and episode_steps == EPISODE_STEPS


def make_task(name: str, **options: Unpack[TaskOptions]) -> LinearPolicyTask:
    """Create the linear-policy task ``name`` (options as ``LinearPolicyTask``)."""
    return LinearPolicyTask(name, **options)
