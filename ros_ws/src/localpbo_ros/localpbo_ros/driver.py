"""The bookkeeping between suite messages and one ask/tell optimizer (DESIGN.md §3–4).

No ROS here: the optimizer node, ``replay --verify`` and ``run --resume`` all use
:class:`Driver`, so the node, the offline verification and the resume rebuild cannot disagree.

* Candidate ids are the optimizer's ids; duel ids are the index of the duel in the optimizer's
  history (0, 1, 2, ... in ask order), so a rebuilt optimizer reissues the same ids.
* θ leaves the driver in task units (``problem.to_native``, DESIGN.md §4).
* :meth:`Driver.offer` validates a decoded :class:`DuelOutcome` against the pending duels
  *before* calling ``tell``; anything that does not answer a pending duel is refused with a
  counter name and the optimizer's state is unchanged.

Run-config ``options`` layout (the bag alone says how the run was made)::

    {"optimizer": {<make_optimizer keyword options, e.g. initial_design, batch_size>},
     "task": {<make_problem keyword options, e.g. episode_steps, value_range>},
     "oracle": {"noise_fraction": float},
     "failure": {"policy": "retry" | "stop", "max_retries": int}}
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from localpbo_core.optimizers import Duel, InvalidOutcome, Outcome, make_optimizer
from localpbo_core.optimizers.preference_optimizer import PreferenceOptimizer
from localpbo_core.optimizers.recommendation import recommend
from localpbo_core.problems import Problem, make_problem
from localpbo_msgs_py import CandidateMsg, DuelOutcome, DuelRequest, Incumbent, RunConfig
from localpbo_msgs_py.records import OutcomeKind

OPTION_SECTIONS = ("optimizer", "task", "oracle", "failure")
FAILURE_POLICIES = ("retry", "stop")


def build_problem(task: str, task_options: Mapping[str, Any]) -> Problem:
    """The problem named ``task`` with its keyword options (``make_problem``)."""
    return make_problem(task, **dict(task_options))


def task_box(problem: Problem) -> tuple[tuple[float, ...], tuple[float, ...]]:
    """θ box in task units: ``to_native`` of the unit cube's corners.

    Raises ValueError when ``to_native`` is not affine per coordinate (the simulator inverts
    it as ``(native - lower) / (upper - lower)``).
    """
    lo = np.asarray(problem.to_native(np.zeros(problem.dim)), dtype=np.float64)
    hi = np.asarray(problem.to_native(np.ones(problem.dim)), dtype=np.float64)
    mid = np.asarray(problem.to_native(np.full(problem.dim, 0.5)), dtype=np.float64)
    if not np.allclose(mid, 0.5 * (lo + hi), rtol=1e-9, atol=1e-12) or np.any(hi <= lo):
        raise ValueError(f"task: {problem.name} maps theta to native units non-affinely")
    return tuple(float(v) for v in lo), tuple(float(v) for v in hi)


def make_run_config(
    *,
    run_id: str,
    algorithm: str,
    task: str,
    seed: int,
    budget: int | None = None,
    optimizer_options: Mapping[str, Any] | None = None,
    task_options: Mapping[str, Any] | None = None,
    noise_fraction: float = 0.1,
    failure_policy: str = "retry",
    max_retries: int = 2,
) -> RunConfig:
    """Validate every setting by building the problem and the optimizer once.

    Raises:
        ValueError: naming the offending setting (unknown algorithm/task/option, bad budget,
            noise fraction, failure policy).
    """
    if failure_policy not in FAILURE_POLICIES:
        raise ValueError(f"failure_policy: {failure_policy!r} is not one of {FAILURE_POLICIES}")
    if isinstance(max_retries, bool) or not isinstance(max_retries, int) or max_retries < 0:
        raise ValueError(f"max_retries: must be an integer >= 0, got {max_retries!r}")
    if not (isinstance(noise_fraction, int | float) and np.isfinite(noise_fraction)):
        raise ValueError(f"noise_fraction: must be a finite number, got {noise_fraction!r}")
    if noise_fraction < 0:
        raise ValueError(f"noise_fraction: must be >= 0, got {noise_fraction!r}")
    opt_options = dict(optimizer_options or {})
    problem = build_problem(task, task_options or {})
    value_range = float(problem.value_range)
    if noise_fraction > 0 and not (np.isfinite(value_range) and value_range > 0):
        raise ValueError(
            f"noise_fraction: task {task!r} with these options has no value range "
            f"({value_range}); pass task option value_range or noise_fraction 0"
        )
    optimizer = make_optimizer(algorithm, problem.dim, seed=seed, budget=budget, **opt_options)
    lower, upper = task_box(problem)
    options = {
        "optimizer": opt_options,
        "task": dict(task_options or {}),
        "oracle": {"noise_fraction": float(noise_fraction)},
        "failure": {"policy": failure_policy, "max_retries": int(max_retries)},
    }
    return RunConfig(
        run_id,
        algorithm.lower(),
        task,
        problem.dim,
        lower,
        upper,
        int(seed),
        optimizer.budget,
        options,
    )


def section(config: RunConfig, name: str) -> dict[str, Any]:
    """One section of the run config's options (empty when absent)."""
    value = config.options.get(name, {})
    if not isinstance(value, dict):
        raise ValueError(f"options.{name}: must be a JSON object, got {type(value).__name__}")
    return dict(value)


def build_optimizer(config: RunConfig) -> PreferenceOptimizer:
    """A fresh optimizer exactly as the run config describes it."""
    return make_optimizer(
        config.algorithm,
        config.dim,
        seed=config.seed,
        budget=config.budget,
        **section(config, "optimizer"),
    )


@dataclass(frozen=True)
class Work:
    """What to publish after an ask: new candidates (task units) and duel requests."""

    candidates: tuple[CandidateMsg, ...]
    requests: tuple[DuelRequest, ...]


@dataclass(frozen=True)
class Verdict:
    """Result of :meth:`Driver.offer`.

    ``accepted``: the outcome was told to the optimizer. Otherwise ``reason`` is a counter
    name: ``failed`` for a failed duel (the caller applies its failure policy), ``duplicate``
    for an exact copy of an accepted outcome (benign: the oracle answered a re-published
    request), anything else a dropped message (``wrong_run``, ``unknown_duel``,
    ``repeated`` — a different answer to an answered duel —, ``mismatched_duel``,
    ``unsupported_kind``, ``rejected``).
    """

    accepted: bool
    reason: str = ""
    detail: str = ""


@dataclass
class Driver:
    """One run's optimizer plus duel-id bookkeeping (see module docstring)."""

    config: RunConfig
    problem: Problem | None = None
    optimizer: PreferenceOptimizer = field(init=False)
    accepted: list[DuelOutcome] = field(init=False, default_factory=list)
    _pending: dict[int, Duel] = field(init=False, default_factory=dict)
    _by_duel: dict[int, DuelOutcome] = field(init=False, default_factory=dict)

    def __post_init__(self) -> None:
        if self.problem is None:
            self.problem = build_problem(self.config.task, section(self.config, "task"))
        if self.problem.dim != self.config.dim:
            raise ValueError(f"dim: run config says {self.config.dim}, task has {self.problem.dim}")
        self.optimizer = build_optimizer(self.config)

    # ------------------------------------------------------------------ state
    @property
    def run_id(self) -> str:
        """The run id stamped on every message."""
        return self.config.run_id

    @property
    def done(self) -> bool:
        """Budget spent and every duel answered."""
        return self.optimizer.done

    @property
    def step_open(self) -> bool:
        """Duels of the current ask are still unanswered."""
        return bool(self._pending)

    @property
    def n_duels(self) -> int:
        """Accepted (decisive) duel outcomes so far."""
        return len(self.accepted)

    def native(self, theta01: np.ndarray) -> tuple[float, ...]:
        """θ in task units."""
        assert self.problem is not None
        return tuple(float(v) for v in np.asarray(self.problem.to_native(theta01)).reshape(-1))

    def candidate_msg(self, candidate_id: int) -> CandidateMsg:
        """The candidate message of an already proposed id."""
        cand = self.optimizer.history.candidates[candidate_id]
        return CandidateMsg(self.run_id, cand.id, self.native(cand.theta))

    def pending_requests(self) -> tuple[DuelRequest, ...]:
        """Requests of the duels still pending, by duel id."""
        return tuple(
            DuelRequest(self.run_id, did, d.first, d.second)
            for did, d in sorted(self._pending.items())
        )

    def pending_candidates(self) -> tuple[CandidateMsg, ...]:
        """Every candidate a pending duel refers to (new and earlier ones), by id."""
        ids = sorted({cid for d in self._pending.values() for cid in (d.first, d.second)})
        return tuple(self.candidate_msg(cid) for cid in ids)

    def incumbent(self) -> Incumbent | None:
        """The preference-defined best so far, in task units."""
        inc = self.optimizer.incumbent
        if inc is None:
            return None
        return Incumbent(self.run_id, inc.id, self.native(inc.theta), self.n_duels)

    def recommendation(self) -> Incumbent | None:
        """The candidate to hand to the user: the highest posterior mean utility given every
        duel so far (:func:`localpbo_core.optimizers.recommendation.recommend`), task units."""
        rec = recommend(self.optimizer)
        if rec is None:
            return None
        return Incumbent(self.run_id, rec.id, self.native(rec.theta), self.n_duels)

    # ------------------------------------------------------------------ ask / offer
    def ask(self) -> Work:
        """Ask the optimizer for the next work (call only when no step is open)."""
        if self._pending:
            raise RuntimeError("ask: duels of the previous ask are still pending")
        first_id = len(self.optimizer.history.duels)
        ask = self.optimizer.ask()
        self._pending = {first_id + i: d for i, d in enumerate(ask.duels)}
        cands = tuple(CandidateMsg(self.run_id, c.id, self.native(c.theta)) for c in ask.candidates)
        return Work(cands, self.pending_requests())

    def offer(self, outcome: DuelOutcome) -> Verdict:
        """Tell ``outcome`` to the optimizer if it answers a pending duel; never raises."""
        if outcome.run_id != self.run_id:
            return Verdict(False, "wrong_run", f"run {outcome.run_id!r}")
        duel = self._pending.get(outcome.duel_id)
        if duel is None:
            issued = len(self.optimizer.history.duels)
            if self._by_duel.get(outcome.duel_id) == outcome:
                return Verdict(False, "duplicate", f"duel {outcome.duel_id} answered again")
            if outcome.duel_id < issued:
                return Verdict(False, "repeated", f"duel {outcome.duel_id} is already answered")
            return Verdict(False, "unknown_duel", f"duel {outcome.duel_id} was never asked")
        if (outcome.first_id, outcome.second_id) != (duel.first, duel.second):
            return Verdict(
                False,
                "mismatched_duel",
                f"duel {outcome.duel_id} is {duel.first} vs {duel.second}, message says "
                f"{outcome.first_id} vs {outcome.second_id}",
            )
        if outcome.kind is OutcomeKind.FAILED:
            return Verdict(False, "failed", outcome.reason)
        if outcome.kind is not OutcomeKind.DECISIVE:
            return Verdict(False, "unsupported_kind", f"{outcome.kind} outcomes are not supported")
        assert outcome.winner_id is not None and outcome.loser_id is not None
        try:
            self.optimizer.tell([Outcome(outcome.winner_id, outcome.loser_id)])
        except InvalidOutcome as exc:
            return Verdict(False, "rejected", str(exc))
        del self._pending[outcome.duel_id]
        self.accepted.append(outcome)
        self._by_duel[outcome.duel_id] = outcome
        return Verdict(True)


@dataclass(frozen=True)
class Rebuild:
    """A driver rebuilt from recorded outcomes, with every candidate it proposed on the way."""

    driver: Driver
    proposed: tuple[CandidateMsg, ...]
    refused: int


def rebuild(config: RunConfig, outcomes: Iterable[DuelOutcome]) -> Rebuild:
    """Re-feed recorded outcomes in order (DESIGN.md §3: same config + outcomes ⇒ same state).

    Uses the node's own acceptance rule (:meth:`Driver.offer`), so the outcomes accepted here
    are the ones the recorded optimizer node accepted. Outcomes that do not answer a pending
    duel are counted in ``refused``.
    """
    driver = Driver(config)
    proposed: list[CandidateMsg] = []
    refused = 0
    if not driver.done:
        proposed.extend(driver.ask().candidates)
    for out in outcomes:
        if driver.done:
            break
        verdict = driver.offer(out)
        if not verdict.accepted:
            refused += 1
            continue
        if not driver.step_open and not driver.done:
            proposed.extend(driver.ask().candidates)
    return Rebuild(driver, tuple(proposed), refused)
