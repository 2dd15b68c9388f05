"""The ask/tell base class shared by every preference optimizer (contract: :mod:`.base`).

Bookkeeping that every algorithm needs lives here:

* candidate ids ``0, 1, 2, ...`` in proposal order;
* the budget counted in *evaluations* (paper App. D.1, "Evaluation and comparison
  budgets": with king-of-the-hill duels, ``2 + 10d`` evaluations give ``1 + 10d``
  comparisons);
* the shared initial design (App. D.1, "same initial data"): ``initial_design`` uniform
  points drawn from a generator derived only from the seed (never from the algorithm), whose
  best is found by sequential duels (candidate ``i+1`` against the current winner); an
  optional ``warm_start`` vector replaces the first design point;
* validation of outcomes *before* any state changes (a rejected ``tell`` leaves the
  optimizer untouched, so the ROS node can drop and count bad messages);
* the incumbent, defined from preferences only (the current king of the hill);
* "can't tell" answers (:class:`~localpbo_core.optimizers.base.Indifferent`), accepted iff
  ``tie_threshold > 0`` (the indifference threshold of the ordinal likelihood,
  :mod:`localpbo_core.surrogate.ordinal`): kept in the history, handed to models by
  :meth:`PreferenceOptimizer.ties`, and never a win (king of the hill keeps the incumbent on a
  tie; the first initial duel, which has no incumbent yet, keeps the earlier candidate).

Subclasses implement :meth:`PreferenceOptimizer._propose` (the next work after the initial
design) and :meth:`PreferenceOptimizer._on_step_complete` (update their own state once every
duel of an ask has been answered).
"""

from __future__ import annotations

import abc
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, TypedDict, Unpack

import numpy as np

from localpbo_core.optimizers.base import Ask, Candidate, Duel, DuelAnswer, Indifferent, Outcome
from localpbo_core.validation import (
    SettingError,
    ValidationError,
    check_float,
    check_int,
    check_theta,
)

if TYPE_CHECKING:  # the protocol module imports torch; the base class does not need it
    from localpbo_core.surrogate.protocol import Surrogate

#: Tag mixed into the seed of the shared initial design; independent of the algorithm.
INITIAL_DESIGN_TAG = 0x1D51
#: Tag mixed into per-step seeds of algorithms (``SeedSequence([seed, TAG, step, ...])``).
STEP_TAG = 0x57E9


class InvalidOutcome(ValidationError):
    """A ``tell`` was rejected; the optimizer's state is unchanged. ``field`` is
    ``"outcome"`` (not an outcome, a self-duel, a duel not asked or answered twice),
    ``"winner"`` or ``"loser"`` (not a known candidate id); ``reason`` says why."""


class BudgetExhausted(RuntimeError):
    """``ask`` was called although every evaluation of the budget has been proposed."""


class PendingDuels(RuntimeError):
    """``ask`` was called while duels of the previous ask are still unanswered."""


@dataclass(frozen=True)
class History:
    """Everything that happened so far, in order.

    Attributes:
        candidates: every proposed candidate (index == id).
        duels: every duel asked, in ask order.
        outcomes: every accepted answer (decisive or "can't tell"), in tell order.
    """

    candidates: tuple[Candidate, ...]
    duels: tuple[Duel, ...]
    outcomes: tuple[DuelAnswer, ...]


def _id_pairs(rows: list[list[int]]) -> np.ndarray:
    """``rows`` of two candidate ids as an ``(m, 2)`` int64 array (``(0, 2)`` for none)."""
    if not rows:
        return np.empty((0, 2), dtype=np.int64)
    return np.array(rows, dtype=np.int64)


def step_generator(seed: int, step: int, *extra: int) -> np.random.Generator:
    """A numpy Generator for one decision step, derived from ``(seed, step, extra)``.

    Every random choice of an algorithm flows from such a generator, so the same seed and
    the same outcomes reproduce the same candidates bit for bit.
    """
    return np.random.default_rng(np.random.SeedSequence([seed, STEP_TAG, step, *extra]))


class RunOptions(TypedDict, total=False):
    """The options every algorithm takes, handed on to :class:`PreferenceOptimizer` (see its
    Args for their meaning and defaults)."""

    initial_design: int
    warm_start: Sequence[float] | np.ndarray | None
    tie_threshold: float


class BatchOptions(RunOptions, total=False):
    """:class:`RunOptions` and the ``batch_size`` of :class:`KingOfTheHillOptimizer`."""

    batch_size: int


def check_multistart(
    num_restarts: object, num_raw_samples: object, spare: int = 0
) -> tuple[int, int]:
    """``(num_restarts, num_raw_samples)`` of a multistart maximisation whose starts are the
    best of the raw samples and ``spare`` other points: integers >= 1, and no more starts
    than there are points."""
    raw = check_int("num_raw_samples", num_raw_samples)
    restarts = check_int("num_restarts", num_restarts)
    if restarts > raw + spare:
        limit = f"num_raw_samples + {spare}" if spare else "num_raw_samples"
        raise SettingError("num_restarts", f"must not exceed {limit}")
    return restarts, raw


def check_one_per_ask(batch_size: object, refusal: str) -> None:
    """Refuse a ``batch_size`` other than 1 for an algorithm that proposes one point per ask;
    ``refusal`` says so in its words."""
    if isinstance(batch_size, bool) or batch_size != 1:
        raise SettingError("batch_size", f"{refusal}, got {batch_size!r}")


class PreferenceOptimizer(abc.ABC):
    """Deterministic ask/tell state machine over (config, seed, outcomes).

    Args:
        dim: dimension d of theta (theta lives in [0,1]^d).
        seed: non-negative integer; all randomness derives from it.
        budget: total number of evaluations (candidates), initial design included.
        initial_design: number of initial uniform points (>= 2), shared by all algorithms.
        warm_start: optional existing controller in [0,1]^d replacing the first design point.
        tie_threshold: indifference threshold ``eps >= 0`` of the ordinal likelihood; "can't
            tell" answers are accepted iff it is > 0.
    """

    #: Registry name, set by subclasses.
    name: str = "base"

    def __init__(
        self,
        dim: int,
        seed: int,
        budget: int,
        initial_design: int = 2,
        warm_start: Sequence[float] | np.ndarray | None = None,
        tie_threshold: float = 0.0,
    ) -> None:
        self.dim = check_int("dim", dim)
        self.tie_threshold = check_float("tie_threshold", tie_threshold, minimum=0.0)
        self.seed = check_int("seed", seed, minimum=0)
        self.initial_design = check_int("initial_design", initial_design, minimum=2)
        self._budget = check_int("budget", budget, minimum=0)
        if self._budget < self.initial_design:
            raise SettingError(
                "budget", f"{budget} is smaller than the initial design ({initial_design})"
            )
        self.warm_start = (
            None if warm_start is None else check_theta("warm_start", warm_start, self.dim)
        )
        design_rng = np.random.default_rng(np.random.SeedSequence([self.seed, INITIAL_DESIGN_TAG]))
        design = design_rng.random((self.initial_design, self.dim))
        if self.warm_start is not None:
            design[0] = self.warm_start
        self._design = design
        self._candidates: list[Candidate] = []
        self._duels: list[Duel] = []
        self._outcomes: list[DuelAnswer] = []
        # Duels of the current ask not answered yet, and the outcomes of the current ask.
        self._pending: list[Duel] = []
        self._step_outcomes: list[DuelAnswer] = []
        self._step_candidates: tuple[Candidate, ...] = ()
        self._incumbent_id: int | None = None
        self._step = 0  # number of completed asks

    # ------------------------------------------------------------------ public state
    @property
    def budget(self) -> int:
        """Total number of evaluations allowed (App. D.1)."""
        return self._budget

    @property
    def evaluations_used(self) -> int:
        """Number of candidates proposed so far (each is evaluated exactly once)."""
        return len(self._candidates)

    @property
    def done(self) -> bool:
        """True when the budget is spent and no duel is pending."""
        return self.evaluations_used >= self._budget and not self._pending

    @property
    def pending_duels(self) -> tuple[Duel, ...]:
        """Duels asked but not answered yet."""
        return tuple(self._pending)

    @property
    def incumbent(self) -> Candidate | None:
        """The preference-defined best candidate (current king of the hill), or None."""
        if self._incumbent_id is None:
            return None
        return self._candidates[self._incumbent_id]

    @property
    def history(self) -> History:
        """Candidates, duels and outcomes so far."""
        return History(tuple(self._candidates), tuple(self._duels), tuple(self._outcomes))

    @property
    def surrogate(self) -> Surrogate | None:
        """The optimizer's last fitted preference model; None if it keeps none (Sobol,
        GLISp) or has not fitted one yet."""
        return None

    @property
    def in_initial_design(self) -> bool:
        """True while the shared initial design is being evaluated and dueled."""
        return self.evaluations_used < self.initial_design or (
            self.evaluations_used == self.initial_design and bool(self._pending)
        )

    # ------------------------------------------------------------------ data for models
    def train_inputs(self) -> np.ndarray:
        """All evaluated thetas, shape (n, d), row i = candidate i."""
        if not self._candidates:
            return np.empty((0, self.dim))
        return np.stack([c.theta for c in self._candidates])

    def comparisons(self) -> np.ndarray:
        """All accepted decisive outcomes as an (m, 2) int64 array of ``[winner, loser]``
        ids."""
        return _id_pairs([[o.winner, o.loser] for o in self._outcomes if isinstance(o, Outcome)])

    def duel_rows(self) -> tuple[np.ndarray, np.ndarray]:
        """Every accepted answer in tell order: ``(m, 2)`` int64 rows (``[winner, loser]`` or,
        for a "can't tell" answer, ``[first, second]``) and an ``(m,)`` bool tie mask."""
        rows = [
            [o.winner, o.loser] if isinstance(o, Outcome) else [o.first, o.second]
            for o in self._outcomes
        ]
        tie = np.array([isinstance(o, Indifferent) for o in self._outcomes], dtype=bool)
        return np.array(rows, dtype=np.int64).reshape(-1, 2), tie

    def ties(self) -> np.ndarray:
        """All accepted "can't tell" answers as a (k, 2) int64 array of ``[first, second]``
        ids."""
        return _id_pairs(
            [[o.first, o.second] for o in self._outcomes if isinstance(o, Indifferent)]
        )

    # ------------------------------------------------------------------ ask / tell
    def ask(self) -> Ask:
        """Return the next candidates to evaluate and the duels wanted.

        Raises:
            PendingDuels: duels of the previous ask are not all answered.
            BudgetExhausted: every evaluation of the budget has been proposed.
        """
        if self._pending:
            raise PendingDuels(
                f"{len(self._pending)} duel(s) of the previous ask are still pending"
            )
        if self.evaluations_used >= self._budget:
            raise BudgetExhausted(f"budget of {self._budget} evaluations is spent")
        n = self.evaluations_used
        if n < self.initial_design:
            if n == 0:
                thetas = [self._design[0], self._design[1]]
                new = self._register(thetas)
                duels = [Duel(new[1].id, new[0].id)]
            else:
                new = self._register([self._design[n]])
                duels = [Duel(new[0].id, self._require_incumbent())]
            ask = Ask(tuple(new), tuple(duels))
        else:
            try:
                ask = self._propose(self._budget - n)
                if not ask.duels:
                    raise RuntimeError(f"{self.name}: an ask must contain at least one duel")
            except BaseException:
                del self._candidates[n:]  # a failed ask leaves no trace
                raise
        return self._open_step(ask)

    def tell(self, outcomes: Iterable[DuelAnswer]) -> None:
        """Record duel outcomes (a subset or all of the pending duels).

        Everything is validated before any state changes.

        Raises:
            InvalidOutcome: an unknown id, a duel that was not asked (or is not pending),
                a repeated outcome, an object that is not an outcome, or a "can't tell"
                answer while ``tie_threshold`` is 0.
        """
        outs = list(outcomes)
        pending = list(self._pending)
        matched: list[Duel] = []
        for out in outs:
            duel = self._match(out, pending)
            pending.remove(duel)
            matched.append(duel)
        # --- validated: commit
        self._pending = pending
        for out in outs:
            self._outcomes.append(out)
            self._step_outcomes.append(out)
        if not self._pending and (outs or self._step_candidates):
            step_outcomes = tuple(self._step_outcomes)
            candidates = self._step_candidates
            self._step_outcomes = []
            self._step_candidates = ()
            if self.evaluations_used <= self.initial_design:
                self._update_king(step_outcomes)
            else:
                self._on_step_complete(candidates, step_outcomes)
            self._step += 1

    # ------------------------------------------------------------------ helpers
    def _open_step(self, ask: Ask) -> Ask:
        """Make ``ask`` the current step: its duels become pending and are logged, and its
        candidates are handed to :meth:`_on_step_complete` once every duel is answered.

        :meth:`ask` calls it for every ask it builds; a subclass that asks follow-up duels
        without new candidates (qEUBO's bracket rounds) calls it with ``Ask((), duels)``.
        """
        self._pending = list(ask.duels)
        self._duels.extend(ask.duels)
        self._step_outcomes = []
        self._step_candidates = ask.candidates
        return ask

    def _match(self, out: object, pending: list[Duel]) -> Duel:
        """Find the pending duel answered by ``out`` or raise InvalidOutcome.

        This is the single place where outcome kinds are dispatched: a win/loss
        :class:`Outcome` (roles ``winner``, ``loser``) or a "can't tell"
        :class:`Indifferent` (roles ``first``, ``second``; only with ``tie_threshold > 0``).
        """
        if isinstance(out, Outcome):
            roles = (("winner", out.winner), ("loser", out.loser))
        elif isinstance(out, Indifferent):
            if self.tie_threshold <= 0:
                raise InvalidOutcome(
                    "outcome", "a 'can't tell' answer needs tie_threshold > 0 (it is 0)"
                )
            roles = (("first", out.first), ("second", out.second))
        else:
            raise InvalidOutcome("outcome", f"not an Outcome or Indifferent: {out!r}")
        n = self.evaluations_used
        for role, cid in roles:
            if isinstance(cid, bool) or not isinstance(cid, int | np.integer):
                raise InvalidOutcome(role, f"candidate id must be an integer, got {cid!r}")
            if not 0 <= cid < n:
                raise InvalidOutcome(role, f"unknown candidate id {cid} (ids are 0..{n - 1})")
        a, b = int(roles[0][1]), int(roles[1][1])
        if a == b:
            raise InvalidOutcome("outcome", f"self-duel {a} vs {b}")
        pair = {a, b}
        for duel in pending:
            if {duel.first, duel.second} == pair:
                return duel
        if any({d.first, d.second} == pair for d in self._duels):
            raise InvalidOutcome("outcome", f"repeated outcome for duel {sorted(pair)}")
        raise InvalidOutcome("outcome", f"duel {sorted(pair)} was not asked")

    def _register(self, thetas: Sequence[np.ndarray]) -> list[Candidate]:
        """Give fresh ids to ``thetas`` (clipped to [0,1]^d, float64, read-only)."""
        new = []
        for theta in thetas:
            arr = np.clip(np.array(theta, dtype=np.float64).reshape(self.dim), 0.0, 1.0)
            if not np.all(np.isfinite(arr)):
                raise RuntimeError(f"{self.name} proposed a non-finite candidate")
            arr.setflags(write=False)
            cand = Candidate(len(self._candidates), arr)
            self._candidates.append(cand)
            new.append(cand)
        return new

    def _set_incumbent(self, candidate_id: int) -> None:
        """Make candidate ``candidate_id`` the incumbent (for rules other than
        :meth:`_update_king`, e.g. a local method's local incumbent)."""
        if not 0 <= candidate_id < len(self._candidates):
            raise RuntimeError(f"{self.name}: incumbent {candidate_id} is not a candidate")
        self._incumbent_id = int(candidate_id)

    def _require_incumbent(self) -> int:
        if self._incumbent_id is None:
            raise RuntimeError("no incumbent yet")
        return self._incumbent_id

    def _update_king(self, outcomes: Sequence[DuelAnswer]) -> bool:
        """King-of-the-hill update (App. D.1): a candidate that beats the incumbent replaces
        it. With several winners against the incumbent in one batch, the first winner in
        proposal order (lowest id) becomes the incumbent. A "can't tell" answer changes
        nothing; without an incumbent yet (the first duel) it crowns the duel's second
        candidate, the earlier one (the warm start if given). Returns True if it changed."""
        if self._incumbent_id is None:
            first = outcomes[0]
            self._incumbent_id = int(
                first.winner if isinstance(first, Outcome) else min(first.first, first.second)
            )
            return True
        winners = sorted(
            int(o.winner)
            for o in outcomes
            if isinstance(o, Outcome) and o.loser == self._incumbent_id
        )
        if winners:
            self._incumbent_id = winners[0]
            return True
        return False

    # ------------------------------------------------------------------ subclass API
    @abc.abstractmethod
    def _propose(self, remaining: int) -> Ask:
        """Return the next work after the initial design. ``remaining`` >= 1 evaluations
        are left; new thetas must be registered with :meth:`_register`."""

    @abc.abstractmethod
    def _on_step_complete(
        self, candidates: tuple[Candidate, ...], outcomes: tuple[DuelAnswer, ...]
    ) -> None:
        """Called once every duel of an ask (after the initial design) is answered."""


class KingOfTheHillOptimizer(PreferenceOptimizer):
    """Base for methods that duel each new candidate against the incumbent (App. D.1).

    Subclasses implement :meth:`_propose_thetas`; the incumbent update rule is
    :meth:`PreferenceOptimizer._update_king`.
    """

    def __init__(
        self, dim: int, seed: int, budget: int, batch_size: int = 1, **run: Unpack[RunOptions]
    ) -> None:
        super().__init__(dim, seed, budget, **run)
        self.batch_size = check_int("batch_size", batch_size)

    def _propose(self, remaining: int) -> Ask:
        q = min(self.batch_size, remaining)
        thetas = self._propose_thetas(q)
        new = self._register(thetas)
        inc = self._require_incumbent()
        return Ask(tuple(new), tuple(Duel(c.id, inc) for c in new))

    def _on_step_complete(
        self, candidates: tuple[Candidate, ...], outcomes: tuple[DuelAnswer, ...]
    ) -> None:
        self._update_king(outcomes)

    @abc.abstractmethod
    def _propose_thetas(self, q: int) -> list[np.ndarray]:
        """Return ``q`` points of [0,1]^d to evaluate next."""
