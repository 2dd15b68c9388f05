"""One run protocol for every path: ids, the acceptance rule for answers, seeds, settings.

``localpbo bench`` (:func:`localpbo_core.loop.run_session`), ``localpbo run``, the ROS
optimizer node in its own process, ``replay --verify`` and ``run --resume`` all drive the
optimizer through a :class:`Session`, so they cannot disagree:

* **Settings**: a run is built from :class:`~localpbo_core.settings.RunSettings`; building a
  session validates them (problem, algorithm, options) and raises
  :class:`~localpbo_core.settings.SettingError` naming the field.
* **Ids**: run-level and monotone. Candidate ids are 0, 1, 2, ... in proposal order and duel
  ids 0, 1, 2, ... in ask order (the optimizer's own indices while nothing was retracted), so
  a rebuilt run reissues the same ids; an id handed out once is never reused, not even after a
  retraction discarded its candidate or duel.
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
* **Retraction** (:meth:`Session.retract`, a person's undo): the latest accepted answer can be
  taken back, and then the one before it, up to ``undo_depth`` answers. The session returns to
  the state it had just before that answer (a fork kept when the answer was offered, so
  exactly the state a run that never got the answer has), the duel is pending again under its
  id, and duels asked since are withdrawn (answers to them get ``WITHDRAWN``). Candidates and
  duels proposed meanwhile keep their spent ids; the next ones get fresh ids.

Same settings and the same answers therefore give bit-identical candidates on every path.
"""

from __future__ import annotations

import copy
import dataclasses
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
    WITHDRAWN = "withdrawn"
    """The duel was withdrawn: a retraction took back an answer it was asked after."""
    RETRACTED = "retracted"
    """A retraction accepted (:meth:`Session.retract`): the answer is taken back."""
    RETRACTION_REFUSED = "retraction_refused"
    """A retraction that cannot be honoured (the detail says why); nothing changed."""


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

    def __init__(
        self, settings: RunSettings, problem: Problem | None = None, *, undo_depth: int = 0
    ) -> None:
        from localpbo_core.threads import use_fast_threads

        use_fast_threads()
        if isinstance(undo_depth, bool) or not isinstance(undo_depth, int) or undo_depth < 0:
            raise SettingError("undo_depth", f"must be an integer >= 0, got {undo_depth!r}")
        self.settings = settings
        self.problem: Problem = build_problem(settings) if problem is None else problem
        self.optimizer: PreferenceOptimizer = build_optimizer(settings, self.problem.dim)
        self.undo_depth = undo_depth
        self.accepted: list[Answer] = []
        self._pending: dict[int, DuelRequest] = {}
        self._step_answers: dict[int, Answer] = {}
        self._by_duel: dict[int, Answer] = {}
        # run ids of the optimizer's candidates and duels (by optimizer index); identity until
        # a retraction discards some, then the next ones continue from the counters
        self._candidate_ids: list[int] = []
        self._duel_ids: list[int] = []
        self._spent = _Spent()
        self._undo: tuple[Session, ...] = ()  # states before the latest answers, oldest first
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
        """An already proposed candidate of the current state (θ in [0,1]^d), by run id.

        Raises:
            KeyError: no such candidate (never proposed, or discarded by a retraction).
        """
        try:
            index = self._candidate_ids.index(candidate_id)
        except ValueError:
            raise KeyError(f"candidate {candidate_id} is not in the run's state") from None
        return self._run_candidate(index)

    def _run_candidate(self, index: int) -> Candidate:
        cand = self.optimizer.history.candidates[index]
        run_id = self._candidate_ids[index]
        return cand if cand.id == run_id else dataclasses.replace(cand, id=run_id)

    def _run_of(self, cand: Candidate | None) -> Candidate | None:
        return None if cand is None else self._run_candidate(cand.id)

    @property
    def spent_ids(self) -> tuple[int, int]:
        """(candidate ids, duel ids) handed out so far: the next ones get these numbers."""
        return self._spent.candidates, self._spent.duels

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
        return self._run_of(self.optimizer.incumbent)

    def recommendation(self) -> Candidate | None:
        """The evaluated candidate with the highest posterior mean utility given every duel
        (:func:`localpbo_core.optimizers.recommendation.recommend`)."""
        from localpbo_core.optimizers.recommendation import recommend

        return self._run_of(recommend(self.optimizer))

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
        twin._candidate_ids = list(self._candidate_ids)
        twin._duel_ids = list(self._duel_ids)
        twin._spent = self._spent.copy()
        return twin

    def _snapshot(self) -> Session:
        """A fork kept for :meth:`retract` (holding no older snapshots: memory stays bounded)."""
        state = self.fork()
        state._undo = ()
        return state

    def _restore(self, state: Session) -> None:
        """Take over ``state`` (an earlier fork of this run), keeping the spent ids."""
        spent = self._spent
        self.__dict__.update(state.__dict__)
        self._spent = spent.copy()

    # ------------------------------------------------------------------ ask / offer
    def ask(self) -> Step:
        """The next work (call only when no duel is pending and the run is not done)."""
        if self._pending:
            raise RuntimeError("ask: duels of the previous ask are still pending")
        ask = self.optimizer.ask()
        for _ in range(len(self.optimizer.history.candidates) - len(self._candidate_ids)):
            self._candidate_ids.append(self._spent.candidates)
            self._spent.candidates += 1
        duels = []
        for d in ask.duels:
            duels.append(
                DuelRequest(
                    self._spent.duels, self._candidate_ids[d.first], self._candidate_ids[d.second]
                )
            )
            self._duel_ids.append(self._spent.duels)
            self._spent.duels += 1
        self._pending = {d.duel_id: d for d in duels}
        self._step_answers = {}
        candidates = tuple(self._run_candidate(c.id) for c in ask.candidates)
        return Step(candidates, tuple(duels))

    def offer(self, answer: Answer) -> Verdict:
        """Accept ``answer`` if it answers a pending duel; never raises, never changes state
        otherwise. The last answer of an ask tells all of them to the optimizer."""
        duel = self._pending.get(answer.duel_id)
        if duel is None:
            if self._by_duel.get(answer.duel_id) == answer:
                return Verdict(Reason.DUPLICATE, f"duel {answer.duel_id} answered again")
            if answer.duel_id in self._by_duel:
                return Verdict(Reason.REPEATED, f"duel {answer.duel_id} is already answered")
            if 0 <= answer.duel_id < self._spent.duels:
                return Verdict(
                    Reason.WITHDRAWN, f"duel {answer.duel_id} was withdrawn by a retraction"
                )
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
        before = self._snapshot() if self.undo_depth else None
        remaining = {k: d for k, d in self._pending.items() if k != duel.duel_id}
        if not remaining:  # the ask is complete: tell every answer, in duel-id order
            answers = sorted([*self._step_answers.values(), answer], key=lambda a: a.duel_id)
            try:
                self.optimizer.tell([self._outcome(a) for a in answers])
            except InvalidOutcome as exc:  # the optimizer's own checks; nothing changed
                return Verdict(Reason.REJECTED, str(exc))
            self._step_answers = {}
        else:
            self._step_answers[duel.duel_id] = answer
        self._pending = remaining
        self.accepted.append(answer)
        self._by_duel[answer.duel_id] = answer
        if before is not None:
            self._undo = (*self._undo, before)[-self.undo_depth :]
        return Verdict(Reason.ACCEPTED)

    def retract(self, duel_id: int) -> Verdict:
        """Take back the answer to ``duel_id`` (a person's undo); never raises.

        Accepted (``Reason.RETRACTED``) iff it is the latest accepted answer and one of the
        last ``undo_depth``: the session then is exactly as it was just before that answer was
        offered (the duel pending again under its id; duels asked since withdrawn), except
        that ids handed out meanwhile stay spent. Otherwise ``RETRACTION_REFUSED`` with the
        reason, and nothing changes.
        """
        if not self.accepted:
            return Verdict(Reason.RETRACTION_REFUSED, "no answer to take back")
        latest = self.accepted[-1].duel_id
        if duel_id != latest:
            if duel_id in self._by_duel:
                why = f"duel {duel_id} is not the latest answer (duel {latest} is)"
            else:
                why = f"duel {duel_id} has no accepted answer"
            return Verdict(Reason.RETRACTION_REFUSED, why)
        if not self._undo:
            return Verdict(
                Reason.RETRACTION_REFUSED,
                f"only the last {self.undo_depth} answers can be taken back",
            )
        *older, state = self._undo
        self._restore(state.fork())
        self._undo = tuple(older)
        return Verdict(Reason.RETRACTED, f"answer to duel {duel_id} taken back")

    def undoable(self) -> int:
        """How many of the latest answers :meth:`retract` can take back, one after another."""
        return len(self._undo)

    def _outcome(self, answer: Answer) -> DuelAnswer:
        """The optimizer's outcome of ``answer`` (run ids mapped to its indices)."""
        first = self._candidate_ids.index(answer.first)
        second = self._candidate_ids.index(answer.second)
        if answer.kind is AnswerKind.INDIFFERENT:
            return Indifferent(first, second)
        assert answer.winner is not None
        return Outcome(first, second) if answer.winner == answer.first else Outcome(second, first)


@dataclass
class _Spent:
    """Ids handed out so far (shared by nothing: each fork copies it)."""

    candidates: int = 0
    duels: int = 0

    def copy(self) -> _Spent:
        return _Spent(self.candidates, self.duels)


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
