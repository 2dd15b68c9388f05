"""The adapter between suite messages and the run protocol (:mod:`localpbo_core.session`).

No ROS here: the optimizer node, ``replay --verify`` and ``run --resume`` all use
:class:`Driver`, whose acceptance rule is the session's (:meth:`Session.offer`), so the node,
the offline verification, the resume rebuild and ``localpbo bench`` cannot disagree.

* The run config (:class:`~localpbo_msgs_py.RunConfig`, the latched message that makes a bag
  self-describing) maps one to one onto :class:`~localpbo_core.settings.RunSettings`
  (:func:`settings_of`, :func:`make_run_config`).
* θ leaves the driver in task units (``problem.to_native``), exactly the numbers the session
  evaluates in-process.
* :meth:`Driver.offer` turns a decoded :class:`DuelOutcome` into an :class:`Answer` and
  returns the session's :class:`Verdict`; answers of another run get ``Reason.WRONG_RUN``.
* :meth:`Driver.speculate` prepares the next ask for every possible answer of the last
  pending duel in a background thread (:mod:`localpbo_core.speculation`); the answer that
  arrives adopts its branch, so :meth:`Driver.ask` returns at once — with exactly the work it
  would have computed.
* A ``retracted`` outcome (a person's undo; runs whose config says a person judges) takes
  back the latest accepted answer
  (:meth:`Session.retract`, up to :data:`UNDO_DEPTH` answers back, one at a time): the run
  returns to its state before that answer, the duel is pending again under its id and the
  duels asked since are withdrawn. The node, ``replay --verify`` and ``run --resume`` all
  re-feed it through :meth:`Driver.offer`, so they rebuild the same run.

Run-config ``options`` layout::

    {"optimizer": {<algorithm options>, "initial_design": int},
     "task": {<problem options, e.g. episode_steps, value_range>},
     "oracle": {"noise_fraction": float, "tie_threshold": float, "indifference": float,
                "kind": "person"},                     # kind only when a person judges
     "failure": {"policy": "retry" | "stop", "max_retries": int},
     "space": {"name", "parameters": [{"name", "lower", "upper", "log", "initial", "unit",
               "description"}], "value_range"}}            # only in space runs

A space run (``localpbo run --space FILE``, optimizer parameter ``space``) tunes the user's
own parameters (:class:`~localpbo_core.space.ParameterSpace`): its task is ``space:<name>``,
the ``space`` section holds the whole space (names, units, scales), so a bag explains itself
and :func:`problem_of` rebuilds the run from the config alone; configs without the section
(older bags, registered tasks) build the registered task as before.

"Can't tell" answers: ``oracle.tie_threshold`` is the indifference threshold ``eps`` of the
ordinal likelihood (:mod:`localpbo_core.surrogate.ordinal`; indifferent outcomes are accepted
iff it is > 0) and ``oracle.indifference`` the simulated oracle's "can't tell" band (a fraction
of the value range). Both are written only when > 0, and an absent key reads as 0, so bags
recorded before ties existed load and verify unchanged.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import dataclass
from typing import Any

import numpy as np

from localpbo_core.optimizers.base import Candidate
from localpbo_core.problems import Problem
from localpbo_core.problems.registry import recorded_problem_options, replayed_problem_options
from localpbo_core.session import (
    Answer,
    DuelRequest,
    Reason,
    Session,
    Step,
    Verdict,
    build_problem,
)
from localpbo_core.settings import (
    DEFAULT_INITIAL_DESIGN,
    DEFAULT_NOISE_FRACTION,
    RunSettings,
    SettingError,
)
from localpbo_core.space import ParameterSpace, parse_space
from localpbo_core.speculation import Branch, Speculation
from localpbo_msgs_py import CandidateMsg, DuelOutcome, Incumbent, RunConfig
from localpbo_msgs_py import DuelRequest as DuelRequestMsg
from localpbo_msgs_py.records import OutcomeKind

OPTION_SECTIONS = ("optimizer", "task", "oracle", "failure", "space")
FAILURE_POLICIES = ("retry", "stop")
DEFAULT_FAILURE_POLICY = "retry"
DEFAULT_MAX_RETRIES = 2
UNDO_DEPTH = 8
"""How many of the latest answers a person can take back, one after another (each keeps one
copy of the optimizer's state); runs without a person keep none."""
PERSON = "person"
"""``options.oracle.kind`` of a run a person judges (absent: the simulated oracle)."""


def section(config: RunConfig, name: str) -> dict[str, Any]:
    """One section of the run config's options (empty when absent)."""
    value = config.options.get(name, {})
    if not isinstance(value, dict):
        raise SettingError(f"options.{name}", f"must be a JSON object, got {type(value).__name__}")
    return dict(value)


def settings_of(config: RunConfig) -> RunSettings:
    """The run settings a run config describes."""
    optimizer = section(config, "optimizer")
    initial = optimizer.pop("initial_design", DEFAULT_INITIAL_DESIGN)
    oracle = section(config, "oracle")
    return RunSettings(
        algorithm=config.algorithm,
        problem=config.task,
        seed=config.seed,
        budget=config.budget,
        initial_design=initial,
        noise_fraction=oracle.get("noise_fraction", DEFAULT_NOISE_FRACTION),
        tie_threshold=oracle.get("tie_threshold", 0.0),
        indifference=oracle.get("indifference", 0.0),
        optimizer_options=optimizer,
        problem_options=replayed_problem_options(config.task, section(config, "task")),
    )


def judged_by_person(config: RunConfig) -> bool:
    """A person answers this run's duels (``options.oracle.kind == "person"``)."""
    return section(config, "oracle").get("kind") == PERSON


def space_of(config: RunConfig) -> ParameterSpace | None:
    """The parameter space of a space run (None for a registered task).

    Raises:
        SettingError: the section is malformed or does not match the config's task and dim.
    """
    if "space" not in config.options:
        return None
    space = parse_space(config.options["space"])
    if config.task != space.name or config.dim != space.dim:
        raise SettingError(
            "options.space", f"describes {space.name} ({space.dim}-D), config {config.task}"
        )
    return space


def problem_of(config: RunConfig) -> Problem:
    """The problem a run config describes: its parameter space, or the registered task."""
    space = space_of(config)
    return build_problem(settings_of(config)) if space is None else space


def task_box(problem: Problem) -> tuple[tuple[float, ...], tuple[float, ...]]:
    """θ box in task units: ``to_native`` of the unit cube's corners.

    A parameter space gives its bounds (its log-scaled coordinates are not affine, but still
    map the unit cube onto the box, monotonically).

    Raises:
        SettingError: ``to_native`` is not affine per coordinate (the box would not describe
            the map).
    """
    if isinstance(problem, ParameterSpace):
        return problem.lower, problem.upper
    lo = np.asarray(problem.to_native(np.zeros(problem.dim)), dtype=np.float64)
    hi = np.asarray(problem.to_native(np.ones(problem.dim)), dtype=np.float64)
    mid = np.asarray(problem.to_native(np.full(problem.dim, 0.5)), dtype=np.float64)
    if not np.allclose(mid, 0.5 * (lo + hi), rtol=1e-9, atol=1e-12) or np.any(hi <= lo):
        raise SettingError("problem", f"{problem.name} maps theta to native units non-affinely")
    return tuple(float(v) for v in lo), tuple(float(v) for v in hi)


def make_run_config(
    run_id: str,
    settings: RunSettings,
    *,
    failure_policy: str = DEFAULT_FAILURE_POLICY,
    max_retries: int = DEFAULT_MAX_RETRIES,
    session: Session | None = None,
    space: ParameterSpace | None = None,
    person: bool = False,
) -> RunConfig:
    """The run config of ``settings``, validated by building the run once.

    ``person``: a person answers the duels (``judge_node``); recorded as ``oracle.kind =
    "person"`` so that a resume continues with a person (:func:`judged_by_person`).

    With ``space`` the run tunes it (task ``space:<name>``, any ``settings.problem`` and
    problem options are replaced); its initial values become the optimizer's ``warm_start``
    unless the settings give one.

    Raises:
        SettingError: naming the refused setting (``failure_policy``, ``max_retries`` or a
            field of :class:`RunSettings`).
    """
    if failure_policy not in FAILURE_POLICIES:
        raise SettingError("failure_policy", f"{failure_policy!r} is not one of {FAILURE_POLICIES}")
    if isinstance(max_retries, bool) or not isinstance(max_retries, int) or max_retries < 0:
        raise SettingError("max_retries", f"must be an integer >= 0, got {max_retries!r}")
    if space is not None:
        settings = space_settings(settings, space)
        session = session or Session(settings, space)
    session = session or Session(settings)
    lower, upper = task_box(session.problem)
    oracle: dict[str, float | str] = {"noise_fraction": settings.noise_fraction}
    if settings.tie_threshold > 0:
        oracle["tie_threshold"] = settings.tie_threshold
    if settings.indifference > 0:
        oracle["indifference"] = settings.indifference
    if person:
        oracle["kind"] = PERSON
    options = {
        "optimizer": {**settings.optimizer_options, "initial_design": settings.initial_design},
        "task": recorded_problem_options(
            settings.problem, dict(settings.problem_options), session.problem
        ),
        "oracle": oracle,
        "failure": {"policy": failure_policy, "max_retries": int(max_retries)},
    }
    if space is not None:
        options["space"] = space.to_dict()
    return RunConfig(
        run_id,
        settings.algorithm,
        settings.problem,
        session.problem.dim,
        lower,
        upper,
        settings.seed,
        session.budget,
        options,
    )


def space_settings(settings: RunSettings, space: ParameterSpace) -> RunSettings:
    """``settings`` for a run over ``space``: task ``space:<name>``, no task options, and the
    space's initial values as ``warm_start`` (unless one is given)."""
    options = dict(settings.optimizer_options)
    warm = space.warm_start()
    if warm is not None and "warm_start" not in options:
        options["warm_start"] = list(warm)
    return settings.replace(problem=space.name, problem_options={}, optimizer_options=options)


def answer_of(outcome: DuelOutcome) -> Answer:
    """The core answer a decoded outcome message carries (not for ``retracted``)."""
    assert outcome.kind is not OutcomeKind.RETRACTED
    duel = DuelRequest(outcome.duel_id, outcome.first_id, outcome.second_id)
    if outcome.kind is OutcomeKind.DECISIVE:
        assert outcome.winner_id is not None
        return Answer.decisive(duel, outcome.winner_id)
    if outcome.kind is OutcomeKind.INDIFFERENT:
        return Answer.indifferent(duel)
    return Answer.failed(duel, outcome.reason)


@dataclass(frozen=True)
class Work:
    """What to publish after an ask: new candidates (task units) and duel requests."""

    candidates: tuple[CandidateMsg, ...]
    requests: tuple[DuelRequestMsg, ...]


class Driver:
    """One run's session, speaking suite messages (see module docstring).

    Args:
        config: the run config (validated by building the session).
        problem: an already built problem of the config's task (else built here).

    Attributes:
        accepted: every accepted outcome message, in acceptance order.
        speculated: accepted answers whose next ask had been prepared (:meth:`speculate`).
    """

    def __init__(self, config: RunConfig, problem: Problem | None = None) -> None:
        self.config = config
        self.session = Session(
            settings_of(config),
            problem if problem is not None else problem_of(config),
            undo_depth=UNDO_DEPTH if judged_by_person(config) else 0,
        )
        self.accepted: list[DuelOutcome] = []
        self.speculated = 0
        self.retracted = 0
        self._speculation: Speculation | None = None
        self._shown: Speculation | None = None  # the last one started: its recommendation
        self._prepared: Step | None = None
        if self.session.problem.dim != config.dim:
            raise SettingError(
                "dim", f"run config says {config.dim}, task has {self.session.problem.dim}"
            )

    # ------------------------------------------------------------------ state
    @property
    def run_id(self) -> str:
        """The run id stamped on every message."""
        return self.config.run_id

    @property
    def done(self) -> bool:
        """Budget spent and every duel answered."""
        return self.session.done

    @property
    def step_open(self) -> bool:
        """Duels of the current ask are still unanswered (an adopted branch's next step is
        not open until :meth:`ask` hands it out)."""
        return self._prepared is None and self.session.step_open

    @property
    def n_duels(self) -> int:
        """Accepted answers so far (decisive and "can't tell")."""
        return self.session.n_duels

    def candidate_msg(self, candidate: Candidate) -> CandidateMsg:
        """The candidate message (task units) of a proposed candidate."""
        native = tuple(float(v) for v in self.session.native(candidate.theta))
        return CandidateMsg(self.run_id, candidate.id, native)

    def pending_requests(self) -> tuple[DuelRequestMsg, ...]:
        """Requests of the duels still pending, by duel id."""
        if self._prepared is not None:
            return ()
        return tuple(
            DuelRequestMsg(self.run_id, d.duel_id, d.first, d.second)
            for d in self.session.pending()
        )

    def pending_candidates(self) -> tuple[CandidateMsg, ...]:
        """Every candidate a pending duel refers to (new and earlier ones), by id."""
        if self._prepared is not None:
            return ()
        return tuple(self.candidate_msg(c) for c in self.session.pending_candidates())

    def incumbent(self) -> Incumbent | None:
        """The preference-defined best so far (king of the hill), in task units."""
        inc = self.session.incumbent
        if inc is None:
            return None
        msg = self.candidate_msg(inc)
        return Incumbent(self.run_id, inc.id, msg.theta, self.n_duels)

    def recommendation(self) -> CandidateMsg | None:
        """The candidate to hand to the user: the highest posterior mean utility given every
        duel so far (:meth:`Session.recommendation`), in task units."""
        rec = self.session.recommendation()
        return None if rec is None else self.candidate_msg(rec)

    # ------------------------------------------------------------------ ask / offer
    def ask(self) -> Work:
        """Ask for the next work (call only when no step is open and the run is not done);
        a step prepared by :meth:`speculate` for the accepted answer is returned as is."""
        step, self._prepared = self._prepared, None
        if step is None:
            step = self.session.ask()
        return Work(tuple(self.candidate_msg(c) for c in step.candidates), self.pending_requests())

    def speculate(self, on_branch: Callable[[Branch], None] | None = None) -> Speculation | None:
        """Start preparing the next ask for every possible answer of the last pending duel
        (background thread, most likely answer first) and return the speculation; None,
        doing nothing, unless exactly one duel is pending. ``on_branch`` gets each prepared
        branch in that thread (:meth:`branch_candidates`: what to evaluate ahead)."""
        self.cancel_speculation()
        if self._prepared is not None or len(self.session.pending()) != 1:
            return None
        self._speculation = Speculation(self.session, recommend=True, on_branch=on_branch)
        self._speculation.start()
        self._shown = self._speculation
        return self._speculation

    def branch_candidates(self, branch: Branch) -> tuple[CandidateMsg, ...]:
        """The new candidates a prepared branch's next ask would propose (task units): what
        an evaluator may run ahead. Never part of the run until that answer arrives."""
        if branch.step is None:
            return ()
        return tuple(
            CandidateMsg(self.run_id, c.id, tuple(float(v) for v in branch.session.native(c.theta)))
            for c in branch.step.candidates
        )

    def prepared_recommendation(self) -> CandidateMsg | None:
        """The recommendation the last speculation computed for the current state (task
        units), or None while it is not known; costs nothing here."""
        spec = self._shown
        rec = None if spec is None else spec.recommendation
        return None if rec is None else self.candidate_msg(rec)

    def cancel_speculation(self) -> None:
        """Drop prepared branches (the one being computed finishes in the background)."""
        if self._speculation is not None:
            self._speculation.cancel()
            self._speculation = None

    def offer(self, outcome: DuelOutcome) -> Verdict:
        """Offer ``outcome`` to the session (never raises); a ``retracted`` one goes to
        :meth:`retract`."""
        if outcome.run_id != self.run_id:
            return Verdict(Reason.WRONG_RUN, f"run {outcome.run_id!r}")
        if outcome.kind is OutcomeKind.RETRACTED:
            return self.retract(outcome)
        answer = answer_of(outcome)
        spec = self._speculation
        if spec is not None and answer in spec.answers:
            self._speculation = None
            branch = spec.take(answer)
            if branch is not None:  # the session as it would be after offer + ask
                self.session = branch.session
                self._prepared = branch.step
                self.speculated += 1
                self.accepted.append(outcome)
                return branch.verdict
        verdict = self.session.offer(answer)
        if verdict.accepted:
            self.accepted.append(outcome)
        return verdict

    def retract(self, outcome: DuelOutcome) -> Verdict:
        """Take back the answer to ``outcome.duel_id`` (``Reason.RETRACTED``: the duel is
        pending again, duels asked since are withdrawn) or refuse (``RETRACTION_REFUSED``
        with the reason; nothing changes)."""
        if self.session.undo_depth == 0:
            return Verdict(
                Reason.RETRACTION_REFUSED,
                "only a run a person judges takes answers back (its run config's "
                'oracle.kind is "person")',
            )
        last = self.accepted[-1] if self.accepted else None
        if last is not None and last.duel_id == outcome.duel_id:
            if (last.first_id, last.second_id) != (outcome.first_id, outcome.second_id):
                return Verdict(
                    Reason.RETRACTION_REFUSED,
                    f"duel {last.duel_id} is {last.first_id} vs {last.second_id}, the "
                    f"retraction says {outcome.first_id} vs {outcome.second_id}",
                )
        verdict = self.session.retract(outcome.duel_id)
        if verdict.reason is Reason.RETRACTED:
            self.cancel_speculation()
            self._prepared = None
            self.accepted.pop()
            self.retracted += 1
        return verdict


@dataclass(frozen=True)
class Rebuild:
    """A driver rebuilt from recorded outcomes, with every candidate and duel request it
    handed out on the way (including those a retraction discarded later)."""

    driver: Driver
    proposed: tuple[CandidateMsg, ...]
    refused: int
    retracted: int = 0
    requests: tuple[DuelRequestMsg, ...] = ()


def rebuild(config: RunConfig, outcomes: Iterable[DuelOutcome]) -> Rebuild:
    """Re-feed recorded outcomes in order (same config + outcomes ⇒ same state).

    Uses the node's own acceptance rule (:meth:`Driver.offer`), so the outcomes accepted here
    are the ones the recorded optimizer node accepted. Outcomes that are not accepted
    (failed duels, duplicates, other runs, refused retractions, ...) are counted in
    ``refused``; accepted retractions in ``retracted``.
    """
    driver = Driver(config)
    proposed: list[CandidateMsg] = []
    requests: list[DuelRequestMsg] = []

    def ask() -> None:
        work = driver.ask()
        proposed.extend(work.candidates)
        requests.extend(work.requests)

    refused = 0
    if not driver.done:
        ask()
    for out in outcomes:
        if driver.done:
            break
        verdict = driver.offer(out)
        if verdict.reason is Reason.RETRACTED:
            continue  # the duel is pending again: nothing to ask
        if not verdict.accepted:
            refused += 1
            continue
        if not driver.step_open and not driver.done:
            ask()
    return Rebuild(driver, tuple(proposed), refused, driver.retracted, tuple(requests))
