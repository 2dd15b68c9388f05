"""Speculative decisions: the next ask prepared for every possible answer of the open duel.

A person needs seconds to judge a duel; the optimizer needs a fraction of one to decide what to
ask next (at d = 33 with a few hundred duels, TuRPBO's decision takes ~150 ms on one core). When
a single duel of a :class:`~localpbo_core.session.Session` is still pending, only a handful of
answers are possible — "first better", "second better", and "can't tell" when the run models
ties — so the next decision can be computed for each of them *while the person watches*:

* each possible answer gets a fork of the session (:meth:`Session.fork`: the optimizer
  deep-copied, the problem shared): one copy is made in the caller's thread, the branches
  fork it in the background (the caller's thread, which in ``localpbo run`` also carries
  the next duel to the page, spends one copy, not one per answer);
* the answers are ordered by how likely the model finds them (:func:`predicted`: the
  optimizer's last fitted surrogate gives ``P(first better)``, ``P(second better)`` and
  ``P(can't tell)`` of the open duel under the ordinal likelihood of
  :mod:`localpbo_core.surrogate.ordinal`), so the branch the person most likely needs is
  ready first; without a surrogate (initial design, Sobol, GLISp) the order is first,
  second, can't tell;
* a background thread offers the answer to its fork and asks it for the next step, one answer
  after another, and hands each finished branch to ``on_branch`` (the node publishes the
  branch's new candidates so that their episodes run ahead, off the critical path);
* when the real answer arrives, :meth:`Speculation.take` returns the branch prepared for it
  (waiting if that very branch is being computed), which the caller adopts in place of its
  session; for any other answer it returns None and the caller decides as usual.

The branches run one after another in one thread: a decision is mostly Python and
small-matrix work that holds the interpreter lock, so a second thread adds no speed (measured:
two TuRPBO branches on Hopper take 178 ms in two threads, 141 ms one after the other).

With ``recommend=True`` the thread then computes, on one more fork, the run's current
recommendation (:meth:`Session.recommendation`: the evaluated candidate with the highest
posterior mean utility), for a person to see while judging, without delaying any decision.

The optimizer is a deterministic state machine over (settings, seed, answers), and a fork
shares nothing mutable with its origin, so an adopted branch holds exactly the state and the
step the session would have produced itself: speculation changes when a decision is computed,
never what it is (``tests/test_speculation.py`` checks bit-identical runs for every
algorithm). An answer that a fork refuses (e.g. "can't tell" in a run without a tie model)
leaves no branch.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from dataclasses import dataclass

from localpbo_core.optimizers.base import Candidate
from localpbo_core.session import Answer, Session, Step, Verdict

__all__ = ["Branch", "Speculation", "possible_answers", "predicted"]


@dataclass(frozen=True)
class Branch:
    """The session after ``answer``: its verdict, the next step (None if the run is done or
    the answer left duels pending) and the seconds the decision took."""

    answer: Answer
    session: Session
    verdict: Verdict
    step: Step | None
    seconds: float


def possible_answers(session: Session) -> tuple[Answer, ...]:
    """Every answer the last pending duel can get: first better, second better, can't tell.

    Raises:
        ValueError: not exactly one duel is pending.
    """
    pending = session.pending()
    if len(pending) != 1:
        raise ValueError(f"speculation needs exactly one pending duel, {len(pending)} are")
    duel = pending[0]
    return (
        Answer.decisive(duel, duel.first),
        Answer.decisive(duel, duel.second),
        Answer.indifferent(duel),
    )


def predicted(session: Session) -> tuple[float, ...] | None:
    """The model's probability of each of :func:`possible_answers` (same order): ``P(first
    better)``, ``P(second better)``, ``P(can't tell)`` of the last pending duel under the
    optimizer's last fitted surrogate (Laplace posterior of paper Sec. 4, ordinal likelihood
    with the run's ``tie_threshold``; ``P(can't tell)`` is 0 without ties). None when the
    optimizer keeps no surrogate yet or the surrogate cannot say.
    """
    surrogate = session.optimizer.surrogate
    if surrogate is None:
        return None
    duel = possible_answers(session)[0]
    try:
        import torch

        a = torch.tensor(session.candidate(duel.first).theta, dtype=torch.float64)
        b = torch.tensor(session.candidate(duel.second).theta, dtype=torch.float64)
        if a.shape[-1] != surrogate.dim:
            return None
        with torch.no_grad():
            p_first = float(surrogate.preference_probability(a, b))
            p_second = float(surrogate.preference_probability(b, a))
            tie = getattr(surrogate, "tie_probability", None)
            p_tie = 0.0 if tie is None else float(tie(a, b))
    except (AttributeError, RuntimeError, TypeError, ValueError):  # a surrogate that cannot say
        return None
    return (p_first, p_second, p_tie)


class Speculation:
    """Branches of ``session`` for each of :func:`possible_answers`, most likely first
    (:func:`predicted`), computed by :meth:`start` in a daemon thread (or by :meth:`run` in
    the caller's); each finished branch is handed to ``on_branch`` (in that thread).

    ``session`` itself is never touched after construction, so the caller may keep offering
    to it; a branch is only valid for the session state it was forked from.

    Attributes:
        answers: the possible answers in the order their branches are computed.
        probabilities: the model's probability of each of ``answers`` (None: no model yet).
    """

    def __init__(
        self,
        session: Session,
        recommend: bool = False,
        on_branch: Callable[[Branch], None] | None = None,
    ) -> None:
        answers = possible_answers(session)
        probs = predicted(session)
        if probs is not None:  # most likely first; ties keep first, second, can't tell
            given = probs
            order = sorted(range(len(answers)), key=lambda i: -given[i])
            answers = tuple(answers[i] for i in order)
            probs = tuple(given[i] for i in order)
        self.answers: tuple[Answer, ...] = answers
        self.probabilities: tuple[float, ...] | None = probs
        self._on_branch = on_branch
        # one copy made here (the caller's thread); the branches fork it in the background
        self._base: Session | None = session.fork()
        self._recommend = recommend
        self.recommendation: Candidate | None = None
        """The current recommendation once computed (``recommend=True``), else None."""
        self._branches: dict[Answer, Branch] = {}
        self._computing: Answer | None = None
        self._cancelled = False
        self._finished = False
        self._cond = threading.Condition()
        self._thread: threading.Thread | None = None

    def start(self) -> Speculation:
        """Compute the branches in a background thread; returns self."""
        self._thread = threading.Thread(target=self.run, name="localpbo-speculation", daemon=True)
        self._thread.start()
        return self

    def run(self) -> None:
        """Compute every branch in order until done or cancelled."""
        base = self._base
        assert base is not None, "a speculation runs once"
        try:
            for answer in self.answers:
                with self._cond:
                    if self._cancelled:
                        return
                    self._computing = answer
                branch = _decide(base.fork(), answer)
                with self._cond:
                    if branch is not None:
                        self._branches[answer] = branch
                    self._computing = None
                    self._cond.notify_all()
                    cancelled = self._cancelled
                if branch is not None and self._on_branch is not None and not cancelled:
                    self._on_branch(branch)
            if self._recommend and not self._cancelled:
                self.recommendation = base.recommendation()
        finally:
            with self._cond:
                self._finished = True
                self._computing = None
                self._base = None
                self._cond.notify_all()

    @property
    def ready(self) -> tuple[Answer, ...]:
        """Answers whose branch is prepared."""
        with self._cond:
            return tuple(self._branches)

    def branches(self) -> tuple[Branch, ...]:
        """The prepared branches (in answer order)."""
        with self._cond:
            return tuple(self._branches.values())

    @property
    def computing(self) -> Answer | None:
        """The answer whose branch is being computed now."""
        with self._cond:
            return self._computing

    def take(self, answer: Answer, timeout: float | None = None) -> Branch | None:
        """The branch prepared for ``answer`` (None if there is none) and stop the rest.

        Waits (at most ``timeout`` seconds) only if that branch is being computed right now:
        finishing it is never slower than starting the same decision again.
        """
        with self._cond:
            self._cancelled = True
            if self._computing == answer:
                self._cond.wait_for(lambda: self._computing != answer, timeout=timeout)
            return self._branches.get(answer)

    def cancel(self) -> None:
        """Compute no further branch (the current one finishes in the background)."""
        with self._cond:
            self._cancelled = True

    def join(self, timeout: float | None = None) -> None:
        """Wait for the background thread (tests and benchmarks)."""
        if self._thread is not None:
            self._thread.join(timeout)


def _decide(fork: Session, answer: Answer) -> Branch | None:
    t0 = time.perf_counter()
    verdict = fork.offer(answer)
    if not verdict.accepted:
        return None
    step = None if (fork.done or fork.step_open) else fork.ask()
    return Branch(answer, fork, verdict, step, time.perf_counter() - t0)
