"""The in-process run: one :class:`~localpbo_core.session.Session` driven to its budget
(paper Sec. 6, App. D.1).

Each candidate is evaluated exactly once with :meth:`Session.evaluate` (the problem's value of
its native parameters with its episode seed); its noise-free value ``problem.true_value``
is recorded for reporting only. Duels are answered by the run's simulated oracle
(:meth:`Session.oracle`, seeded per duel) from the stored evaluation values and offered to
the session with the same acceptance rule as the ROS nodes; the optimizer only ever receives
outcomes (winner id, loser id).

One record per evaluation with the columns of :data:`RESULT_COLUMNS`. ``best_seen`` and
``cumulative`` are the paper's metrics (App. D.1: best-seen ``f_best`` and cumulative
``sum_k f_k``) on true values. ``decision_seconds`` is the optimizer's own time in ask and
tell (episodes and oracle excluded), split evenly over the candidates of an ask, so the
column sums to the optimizer's total time. :class:`RunTrace` keeps what the run exchanged
(candidates, their values, duels and answers) for comparisons across paths.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from localpbo_core.session import Answer, Session

RESULT_COLUMNS = (
    "problem",
    "algorithm",
    "seed",
    "evaluation",
    "candidate_id",
    "f_true",
    "best_seen",
    "cumulative",
    "decision_seconds",
)


@dataclass(frozen=True)
class EvaluationRecord:
    """One row of ``results.csv`` (see :data:`RESULT_COLUMNS`)."""

    problem: str
    algorithm: str
    seed: int
    evaluation: int
    candidate_id: int
    f_true: float
    best_seen: float
    cumulative: float
    decision_seconds: float

    def as_row(self) -> list[object]:
        """Values in :data:`RESULT_COLUMNS` order."""
        return [getattr(self, c) for c in RESULT_COLUMNS]


@dataclass
class RunTrace:
    """What one run exchanged, in order (for comparisons across paths and for storage).

    Attributes:
        native: candidate id -> parameters in the problem's units, as evaluated.
        values: candidate id -> the evaluated value (episode return) the oracle compared.
        answers: every accepted answer, in acceptance order.
        records: one :class:`EvaluationRecord` per evaluation.
    """

    native: dict[int, tuple[float, ...]] = field(default_factory=dict)
    values: dict[int, float] = field(default_factory=dict)
    answers: list[Answer] = field(default_factory=list)
    records: list[EvaluationRecord] = field(default_factory=list)


def run_session(
    session: Session,
    on_evaluation: Callable[[EvaluationRecord], None] | None = None,
    *,
    trace: RunTrace | None = None,
    on_step: Callable[[RunTrace], None] | None = None,
) -> RunTrace:
    """Drive ``session`` until its budget is spent; return what the run exchanged.

    Args:
        session: a fresh session (its settings name the problem, algorithm, seed, noise),
            or, with ``trace``, a session in the state this loop left it in after ``trace``.
        on_evaluation: called with each record as soon as it is complete.
        trace: what the run exchanged before ``session``'s state (a run continued from a
            checkpoint, :mod:`localpbo_core.checkpoints`); it is extended in place, and the
            run goes on as if it had never stopped.
        on_step: called with the trace after each step that evaluated candidates, when
            ``session`` is between two steps (the state a checkpoint keeps).
    """
    settings = session.settings
    problem = session.problem
    oracle = session.oracle()
    trace = RunTrace() if trace is None else trace
    best = -np.inf
    cumulative = 0.0
    for r in trace.records:  # the sums of the records as this loop made them
        best = max(best, r.f_true)
        cumulative += r.f_true
    carry = 0.0  # optimizer time of asks without candidates, charged to the next candidates
    while not session.done:
        t0 = time.perf_counter()
        step = session.ask()
        decide = time.perf_counter() - t0
        pending: list[tuple[int, float]] = []  # (candidate id, f_true)
        for cand in step.candidates:
            trace.native[cand.id] = tuple(float(v) for v in session.native(cand.theta))
            trace.values[cand.id] = session.evaluate(cand)
            pending.append((cand.id, float(problem.true_value(cand.theta))))
        for duel in step.duels:
            judged = oracle.judge(duel.duel_id, trace.values[duel.first], trace.values[duel.second])
            if judged is None:
                answer = Answer.indifferent(duel)
            else:
                answer = Answer.decisive(duel, duel.first if judged else duel.second)
            t0 = time.perf_counter()
            verdict = session.offer(answer)
            decide += time.perf_counter() - t0
            if not verdict.accepted:
                raise RuntimeError(f"duel {duel.duel_id}: {verdict.reason.value} {verdict.detail}")
            trace.answers.append(answer)
        decide += carry
        if not pending:
            carry = decide
            continue
        carry = 0.0
        share = decide / len(pending)
        for cid, f_true in pending:
            best = max(best, f_true)
            cumulative += f_true
            rec = EvaluationRecord(
                problem=problem.name,
                algorithm=settings.algorithm,
                seed=settings.seed,
                evaluation=len(trace.records) + 1,
                candidate_id=cid,
                f_true=f_true,
                best_seen=float(best),
                cumulative=cumulative,
                decision_seconds=share,
            )
            trace.records.append(rec)
            if on_evaluation is not None:
                on_evaluation(rec)
        if on_step is not None:
            on_step(trace)
    return trace
