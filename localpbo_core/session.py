"""One run protocol for every path: ids, the acceptance rule for answers, seeds, settings.

``localpbo bench`` (:func:`localpbo_core.loop.run_session`), ``localpbo run``, the ROS
optimizer node in its own process, ``replay --verify`` and ``run --resume`` all drive the
optimizer through a :class:`Session`, so they cannot disagree:

* **Settings**: a run is built from :class:`~localpbo_core.settings.RunSettings`; building a
  session validates them (problem, algorithm, options) and raises
  :class:`~localpbo_core.settings.SettingError` naming the field.
* **Ids**: candidate ids are the optimizer's ids (0, 1, 2, ... in proposal order); the id of
  a duel is its index in the optimizer's history (0, 1, 2, ... in ask order), so a rebuilt
  run reissues the same ids.
* **Seeds** (:mod:`localpbo_core.seeds`): candidate ``k`` is evaluated once with
  ``episode_seed(run seed, k)`` on the parameters ``problem.to_native(theta)`` — the very
  numbers a simulator or controller receives — and duel ``k`` is answered by the simulated
  oracle with ``duel_seed(run seed, k)``.
* **Acceptance** (:meth:`Session.offer`): an :class:`Answer` is checked against the pending
  duels before anything changes and gets a :class:`Verdict` with a :class:`Reason` code.
  The answers of one ask are told to the optimizer together, in duel-id order, once the last
  one is accepted, so the order in which answers arrive never changes the run. "Can't tell"
  answers (``AnswerKind.INDIFFERENT``) are accepted iff the run's ``tie_threshold`` is > 0
  (told as :class:`~localpbo_core.optimizers.base.Indifferent`), else refused with
  ``UNSUPPORTED_KIND``.

Same settings and the same answers therefore give bit-identical candidates on every path.
"""

from __future__ import annotations

import copy
import enum
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from localpbo_core.optimizers.base import Candidate, DuelAnswer, Indifferent, Outcome
from localpbo_core.optimizers.preference_optimizer import InvalidOutcome, PreferenceOptimizer
from localpbo_core.seeds import duel_seed, episode_seed
from localpbo_core.settings import RunSettings, SettingError

if TYPE_CHECKING:
    from localpbo_core.problems import DuelOracle, Problem

__all__ = [
    "Answer",
    "AnswerKind",
    "DuelRequest",
    "Reason",
    "RunSettings",
    "Session",
    "SettingError",
    "Step",
    "Verdict",
    "duel_seed",
    "episode_seed",
]


class AnswerKind(enum.Enum):
    """What an oracle (simulated or a person) answered to a duel."""

    DECISIVE = "decisive"
    """One candidate was preferred (``Answer.winner``)."""
    INDIFFERENT = "indifferent"
    """Neither was preferred ("can't tell")."""
    FAILED = "failed"
    """No answer could be given (an episode failed, an evaluator timed out)."""


@dataclass(frozen=True)
class DuelRequest:
    """Duel ``duel_id`` between candidates ``first`` and ``second``."""

    duel_id: int
    first: int
    second: int


@dataclass(frozen=True)
class Answer:
    """An answer to duel ``duel_id`` (which repeats its two candidates).

    Build one with :meth:`decisive`, :meth:`indifferent` or :meth:`failed`.
    """

    duel_id: int
    first: int
    second: int
    kind: AnswerKind
    winner: int | None = None
    reason: str = ""

    @classmethod
    def decisive(cls, duel: DuelRequest, winner: int) -> Answer:
        """``winner`` (one of the duel's candidates) was preferred."""
        return cls(duel.duel_id, duel.first, duel.second, AnswerKind.DECISIVE, winner)

    @classmethod
    def indifferent(cls, duel: DuelRequest) -> Answer:
        """Neither candidate was preferred."""
        return cls(duel.duel_id, duel.first, duel.second, AnswerKind.INDIFFERENT)

    @classmethod
    def failed(cls, duel: DuelRequest, reason: str) -> Answer:
        """The duel could not be answered, for ``reason``."""
        return cls(duel.duel_id, duel.first, duel.second, AnswerKind.FAILED, reason=reason)

    @property
    def loser(self) -> int | None:
        """The candidate that was not preferred (decisive answers)."""
        if self.winner is None:
            return None
        return self.second if self.winner == self.first else self.first


class Reason(enum.Enum):
    """Why :meth:`Session.offer` did or did not accept an answer (a counter name each)."""

    ACCEPTED = "accepted"
    """Recorded; told to the optimizer when its ask is complete."""
    FAILED = "failed"
    """A failed duel: nothing changed; the caller applies its failure policy."""
    DUPLICATE = "duplicate"
    """An exact copy of an accepted answer (benign: a re-published request answered again)."""
    REPEATED = "repeated"
    """A different answer to a duel that is already answered."""
    UNKNOWN_DUEL = "unknown_duel"
    """The duel id was never asked."""
    MISMATCHED_DUEL = "mismatched_duel"
    """The answer names other candidates than the duel it answers."""
    BAD_WINNER = "bad_winner"
    """A decisive answer whose winner is not one of the duel's candidates."""
    UNSUPPORTED_KIND = "unsupported_kind"
    """An answer kind the run does not use (e.g. "can't tell" without a tie model)."""
    WRONG_RUN = "wrong_run"
    """For adapters whose messages carry a run id: the answer belongs to another run."""
    REJECTED = "rejected"
    """The optimizer's own checks refused the answers of the ask (nothing changed)."""
    NOT_RUNNING = "not_running"
    """For adapters: the run has not started or has ended."""


@dataclass(frozen=True)
class Verdict:
    """Result of :meth:`Session.offer`: a :class:`Reason` and a human-readable detail."""

    reason: Reason
    detail: str = ""

    @property
    def accepted(self) -> bool:
        """True if the answer was recorded."""
        return self.reason is Reason.ACCEPTED


@dataclass(frozen=True)
class Step:
    """The work of one ask: candidates to evaluate (possibly none) and duels to answer."""

    candidates: tuple[Candidate, ...]
    duels: tuple[DuelRequest, ...]


class Session:
    """One run: its settings, problem, optimizer and the duel bookkeeping.

    Args:
        settings: the run (validated here: problem, algorithm and options are built once).
        problem: an already built problem for ``settings.problem`` (else built here).

    Raises:
        SettingError: a setting the problem or algorithm refuses; ``field`` names it
            (``problem``, ``algorithm``, ``budget``, ``noise_fraction``,
            ``optimizer_options.<key>``, ``problem_options.<key>``).
    """

    def __init__(self, settings: RunSettings, problem: Problem | None = None) -> None:
        from localpbo_core.threads import use_fast_threads

        use_fast_threads()
        self.settings = settings
        self.problem: Problem = build_problem(settings) if problem is None else problem
        self.optimizer: PreferenceOptimizer = build_optimizer(settings, self.problem.dim)
        self.accepted: list[Answer] = []
        self._pending: dict[int, DuelRequest] = {}
        self._step_answers: dict[int, Answer] = {}
        self._by_duel: dict[int, Answer] = {}
        self.oracle()  # validates the noise against the problem's value range

    # ------------------------------------------------------------------ state
    @property
    def done(self) -> bool:
        """Budget spent and every duel answered."""
        return self.optimizer.done and not self._pending

    @property
    def step_open(self) -> bool:
        """Duels of the current ask are still unanswered."""
        return bool(self._pending)

    @property
    def n_duels(self) -> int:
        """Accepted answers so far (decisive and, with ``tie_threshold > 0``, "can't
        tell")."""
        return len(self.accepted)

    @property
    def budget(self) -> int:
        """Evaluations of the run, initial design included."""
        return self.optimizer.budget

    @property
    def evaluations(self) -> int:
        """Candidates proposed so far (each is evaluated once)."""
        return self.optimizer.evaluations_used

    def candidate(self, candidate_id: int) -> Candidate:
        """An already proposed candidate (θ in [0,1]^d)."""
        return self.optimizer.history.candidates[candidate_id]

    def native(self, theta: np.ndarray) -> np.ndarray:
        """θ in the problem's own units (what a simulator or controller receives)."""
        return np.asarray(self.problem.to_native(theta), dtype=np.float64).reshape(-1)

    def episode_seed(self, candidate_id: int) -> int:
        """The seed of candidate ``candidate_id``'s one evaluation."""
        return episode_seed(self.settings.seed, candidate_id)

    def evaluate(self, candidate: Candidate) -> float:
        """One evaluation of ``candidate`` as every path runs it: the problem's value of
        ``native(θ)`` with the candidate's episode seed."""
        return evaluate_native(
            self.problem, self.native(candidate.theta), self.episode_seed(candidate.id)
        )

    def oracle(self) -> DuelOracle:
        """The simulated oracle of this run (per-duel seeds, the settings' noise).

        Raises:
            SettingError: ``noise_fraction`` > 0 for a problem without a value range.
        """
        from localpbo_core.problems import DuelOracle

        return DuelOracle(
            self.problem,
            self.settings.noise_fraction,
            self.settings.seed,
            indifference=self.settings.indifference,
        )

    def pending(self) -> tuple[DuelRequest, ...]:
        """Duels of the current ask not answered yet, by duel id."""
        return tuple(self._pending[k] for k in sorted(self._pending))

    def pending_candidates(self) -> tuple[Candidate, ...]:
        """Every candidate a pending duel refers to (new and earlier ones), by id."""
        ids = sorted({c for d in self._pending.values() for c in (d.first, d.second)})
        return tuple(self.candidate(c) for c in ids)

    @property
    def incumbent(self) -> Candidate | None:
        """The preference-defined best so far (king of the hill)."""
        return self.optimizer.incumbent

    def recommendation(self) -> Candidate | None:
        """The evaluated candidate with the highest posterior mean utility given every duel
        (:func:`localpbo_core.optimizers.recommendation.recommend`)."""
        from localpbo_core.optimizers.recommendation import recommend

        return recommend(self.optimizer)

    def fork(self) -> Session:
        """An independent copy of the run's state: the optimizer is deep-copied, the problem
        and settings (immutable for the run) are shared. Offering to or asking the copy never
        changes this session (:mod:`localpbo_core.speculation`)."""
        twin = copy.copy(self)
        twin.optimizer = copy.deepcopy(self.optimizer)
        twin.accepted = list(self.accepted)
        twin._pending = dict(self._pending)
        twin._step_answers = dict(self._step_answers)
        twin._by_duel = dict(self._by_duel)
        return twin

    # ------------------------------------------------------------------ ask / offer
    def ask(self) -> Step:
        """The next work (call only when no duel is pending and the run is not done)."""
        if self._pending:
            raise RuntimeError("ask: duels of the previous ask are still pending")
        first_id = len(self.optimizer.history.duels)
        ask = self.optimizer.ask()
        duels = tuple(DuelRequest(first_id + i, d.first, d.second) for i, d in enumerate(ask.duels))
        self._pending = {d.duel_id: d for d in duels}
        self._step_answers = {}
        return Step(ask.candidates, duels)

    def offer(self, answer: Answer) -> Verdict:
        """Accept ``answer`` if it answers a pending duel; never raises, never changes state
        otherwise. The last answer of an ask tells all of them to the optimizer."""
        duel = self._pending.get(answer.duel_id)
        if duel is None:
            if self._by_duel.get(answer.duel_id) == answer:
                return Verdict(Reason.DUPLICATE, f"duel {answer.duel_id} answered again")
            if 0 <= answer.duel_id < len(self.optimizer.history.duels):
                return Verdict(Reason.REPEATED, f"duel {answer.duel_id} is already answered")
            return Verdict(Reason.UNKNOWN_DUEL, f"duel {answer.duel_id} was never asked")
        if (answer.first, answer.second) != (duel.first, duel.second):
            return Verdict(
                Reason.MISMATCHED_DUEL,
                f"duel {duel.duel_id} is {duel.first} vs {duel.second}, the answer says "
                f"{answer.first} vs {answer.second}",
            )
        if answer.kind is AnswerKind.FAILED:
            return Verdict(Reason.FAILED, answer.reason)
        if answer.kind is AnswerKind.INDIFFERENT:
            if self.settings.tie_threshold <= 0:
                return Verdict(
                    Reason.UNSUPPORTED_KIND,
                    "indifferent answers are not used (the run's tie_threshold is 0)",
                )
            if answer.winner is not None:
                return Verdict(Reason.BAD_WINNER, "an indifferent answer names no winner")
        elif answer.kind is not AnswerKind.DECISIVE:
            return Verdict(Reason.UNSUPPORTED_KIND, f"{answer.kind.value} answers are not used")
        elif answer.winner not in (duel.first, duel.second):
            return Verdict(
                Reason.BAD_WINNER, f"winner {answer.winner} is not in duel {duel.duel_id}"
            )
        remaining = {k: d for k, d in self._pending.items() if k != duel.duel_id}
        if not remaining:  # the ask is complete: tell every answer, in duel-id order
            answers = sorted([*self._step_answers.values(), answer], key=lambda a: a.duel_id)
            try:
                self.optimizer.tell([_outcome(a) for a in answers])
            except InvalidOutcome as exc:  # the optimizer's own checks; nothing changed
                return Verdict(Reason.REJECTED, str(exc))
            self._step_answers = {}
        else:
            self._step_answers[duel.duel_id] = answer
        self._pending = remaining
        self.accepted.append(answer)
        self._by_duel[answer.duel_id] = answer
        return Verdict(Reason.ACCEPTED)


def _outcome(answer: Answer) -> DuelAnswer:
    if answer.kind is AnswerKind.INDIFFERENT:
        return Indifferent(answer.first, answer.second)
    assert answer.winner is not None and answer.loser is not None
    return Outcome(answer.winner, answer.loser)


def build_problem(settings: RunSettings) -> Problem:
    """The problem of ``settings`` with its options; SettingError names a refused one."""
    from localpbo_core.problems import available_problems, make_problem

    if settings.problem not in available_problems():
        raise SettingError(
            "problem",
            f"unknown problem {settings.problem!r}; available: {', '.join(available_problems())}",
        )
    try:
        return make_problem(settings.problem, **dict(settings.problem_options))
    except SettingError as exc:
        raise exc.within("problem_options") from None
    except (ValueError, TypeError) as exc:
        raise SettingError("problem_options", str(exc)) from None


def build_optimizer(settings: RunSettings, dim: int) -> PreferenceOptimizer:
    """A fresh optimizer exactly as ``settings`` describe it, for a ``dim``-D problem."""
    from localpbo_core.optimizers.registry import make_optimizer, optimizer_options

    allowed = optimizer_options(settings.algorithm)
    for key in settings.optimizer_options:
        if key not in allowed:
            raise SettingError(
                f"optimizer_options.{key}",
                f"not an option of {settings.algorithm!r}; allowed: {', '.join(allowed)}",
            )
    try:
        return make_optimizer(
            settings.algorithm,
            dim,
            seed=settings.seed,
            budget=settings.budget,
            initial_design=settings.initial_design,
            tie_threshold=settings.tie_threshold,
            **dict(settings.optimizer_options),
        )
    except SettingError as exc:
        if exc.field in ("algorithm", "seed", "budget", "initial_design"):
            raise
        raise exc.within("optimizer_options") from None
    except (ValueError, TypeError) as exc:
        raise SettingError("optimizer_options", str(exc)) from None


def evaluate_native(problem: Problem, native: np.ndarray, seed: int) -> float:
    """One evaluation of parameters given in the problem's own units (``evaluate_native``)."""
    return float(problem.evaluate_native(np.asarray(native, dtype=np.float64), seed))
