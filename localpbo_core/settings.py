"""The settings of one run, their defaults and their validation.

A run is fully described by :class:`RunSettings`: algorithm, problem, seed, budget, shared
initial design, oracle noise and the keyword options of the algorithm and of the problem.
Every path (``localpbo bench``, ``localpbo run``, the ROS nodes, ``replay --verify``,
``run --resume``) builds its run from these settings, so each default is written here once:

* ``DEFAULT_INITIAL_DESIGN = 2`` random points shared by every algorithm (paper App. D.1,
  "same initial data"; policy search uses 5 d);
* ``DEFAULT_NOISE_FRACTION = 0.1``: oracle noise std as a fraction of the problem's
  approximate value range (paper Sec. 6 and App. D.1, "Noise model");
* ``localpbo run`` tunes ``DEFAULT_ALGORITHM`` (``hybrid_probe0.5_s0.5``, a preset of the hybrid:
  the choice of the stored runs, docs/algorithms.md) on ``DEFAULT_PROBLEM`` (Swimmer);
* the budget ``initial design + 10 d`` evaluations (:func:`default_budget`; 62 on
  Hartmann 6, paper App. D.1 "Evaluation and comparison budgets");
* ``tie_threshold`` 0 (the paper's likelihood, no "can't tell" answers); a run whose judge
  may answer "can't tell" should use ``DEFAULT_TIE_THRESHOLD = 0.25``, what ``--tie-threshold``
  without a value gives (the smallest threshold of the tie ablation, never worse than
  dropping ties there; ``localpbo_core.benchmarks.tie_ablation``).

Bad settings raise :class:`~localpbo_core.validation.SettingError`, which carries the
offending field and the reason as data (``exc.field``, ``exc.reason``), so a caller maps the
field to its own name (a CLI flag, a ROS parameter) without parsing text.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from localpbo_core.presets import expand
from localpbo_core.validation import SettingError, check_float, check_int

__all__ = [
    "BUDGET_PER_DIMENSION",
    "DEFAULT_ALGORITHM",
    "DEFAULT_INITIAL_DESIGN",
    "DEFAULT_NOISE_FRACTION",
    "DEFAULT_PROBLEM",
    "DEFAULT_TIE_THRESHOLD",
    "RunSettings",
    "SettingError",
    "default_budget",
]

DEFAULT_INITIAL_DESIGN = 2
"""Shared random initial points of a run (paper App. D.1)."""

DEFAULT_NOISE_FRACTION = 0.1
"""Oracle noise std as a fraction of the problem's value range (paper App. D.1)."""

DEFAULT_TIE_THRESHOLD = 0.25
"""The indifference threshold ``eps`` to use when a judge may answer "can't tell" (latent
units; :mod:`localpbo_core.surrogate.ordinal`). Runs default to 0, the paper's model."""

DEFAULT_ALGORITHM = "hybrid_probe0.5_s0.5"
"""The algorithm (or preset, :mod:`localpbo_core.presets`) of ``localpbo run`` and of the
optimizer node when none is chosen: the one the stored runs pick by the rule of
:mod:`localpbo_core.experiments.beyond` (among the algorithms run on all 18 main problems of
Sec. 6, best or tied on the most; ``tests/test_which_algorithm.py`` checks it)."""

DEFAULT_PROBLEM = "swimmer"
"""The embedded default task: the 16-D Swimmer linear policy (162 evaluations, ~20 s)."""

BUDGET_PER_DIMENSION = 10
"""The default budget adds this many evaluations per dimension to the initial design."""


def default_budget(dim: int, initial_design: int = DEFAULT_INITIAL_DESIGN) -> int:
    """``initial_design + 10 d`` evaluations (paper App. D.1)."""
    return int(initial_design) + BUDGET_PER_DIMENSION * int(dim)


def _check_options(field: str, value: object) -> dict[str, Any]:
    if not isinstance(value, Mapping):
        raise SettingError(field, f"must be a mapping of option names to values, got {value!r}")
    for key in value:
        if not isinstance(key, str) or not key:
            raise SettingError(field, f"option names must be non-empty strings, got {key!r}")
    return dict(value)


@dataclass(frozen=True)
class RunSettings:
    """Everything that defines a run; equal settings and outcomes give an identical run.

    Args:
        algorithm: registered algorithm name (``make_optimizer``) or preset label
            (:mod:`localpbo_core.presets`), lower-cased. A preset is expanded here: the field
            holds its algorithm and ``optimizer_options`` its options (then those given), so
            the run is the one with the options given explicitly.
        problem: registered problem name (``make_problem``), e.g. ``hartmann6``, ``hopper``.
        seed: run seed (>= 0); the optimizer, the episode seeds and the oracle noise derive
            from it (:mod:`localpbo_core.seeds`).
        budget: evaluations including the initial design; ``None`` for
            :func:`default_budget`.
        initial_design: shared random initial points (>= 2).
        noise_fraction: oracle noise std as a fraction of the problem's value range (>= 0).
        tie_threshold: the indifference threshold ``eps >= 0`` of the ordinal likelihood
            (latent-utility units, probit noise sigma_n = 1;
            :mod:`localpbo_core.surrogate.ordinal`), passed to every optimizer; "can't tell"
            answers are accepted iff it is > 0. 0 is the paper's model.
        indifference: the simulated oracle answers "can't tell" when its noisy difference
            is below this fraction of the problem's value range (>= 0; 0 never; > 0 needs
            ``tie_threshold > 0``).
        optimizer_options: keyword options of the algorithm (e.g. ``batch_size``).
        problem_options: keyword options of the problem (e.g. ``episode_steps``).

    Raises:
        SettingError: a field of the wrong type or out of range (checked at construction;
            whether the algorithm and problem accept the options is checked when a
            :class:`~localpbo_core.session.Session` is built).
    """

    algorithm: str
    problem: str
    seed: int = 0
    budget: int | None = None
    initial_design: int = DEFAULT_INITIAL_DESIGN
    noise_fraction: float = DEFAULT_NOISE_FRACTION
    tie_threshold: float = 0.0
    indifference: float = 0.0
    optimizer_options: Mapping[str, Any] = field(default_factory=dict)
    problem_options: Mapping[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        for name in ("algorithm", "problem"):
            value = getattr(self, name)
            if not isinstance(value, str) or not value.strip():
                raise SettingError(name, f"must be a non-empty name, got {value!r}")
        algorithm, options = expand(
            self.algorithm.strip().lower(),
            _check_options("optimizer_options", self.optimizer_options),
        )
        object.__setattr__(self, "algorithm", algorithm)
        object.__setattr__(self, "problem", self.problem.strip())
        check_int("seed", self.seed, minimum=0)
        if self.budget is not None:
            check_int("budget", self.budget, minimum=1)
        check_int("initial_design", self.initial_design, minimum=2)
        if self.budget is not None and self.budget < self.initial_design:
            raise SettingError(
                "budget",
                f"{self.budget} is smaller than the initial design ({self.initial_design})",
            )
        object.__setattr__(
            self, "noise_fraction", check_float("noise_fraction", self.noise_fraction, minimum=0.0)
        )
        object.__setattr__(
            self, "tie_threshold", check_float("tie_threshold", self.tie_threshold, minimum=0.0)
        )
        object.__setattr__(
            self, "indifference", check_float("indifference", self.indifference, minimum=0.0)
        )
        if self.indifference > 0 and self.tie_threshold == 0:
            raise SettingError(
                "indifference",
                "an oracle that answers 'can't tell' needs tie_threshold > 0 (else its "
                "answers are refused)",
            )
        for reserved in ("dim", "seed", "budget", "initial_design", "tie_threshold"):
            if reserved in options:
                raise SettingError(
                    f"optimizer_options.{reserved}", "is a run setting of its own, not an option"
                )
        object.__setattr__(self, "optimizer_options", options)
        object.__setattr__(
            self, "problem_options", _check_options("problem_options", self.problem_options)
        )

    def replace(self, **changes: Any) -> RunSettings:
        """A copy with some fields changed (validated again)."""
        values = {name: getattr(self, name) for name in self.__dataclass_fields__}
        values.update(changes)
        return RunSettings(**values)
