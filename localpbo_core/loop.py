"""The in-process tuning loop: problem -> optimizer -> oracle (paper Sec. 6, App. D.1).

Each candidate is evaluated exactly once with ``problem.evaluate(theta, seed=...)`` where
the episode seed is derived from the run seed and the candidate id; its noise-free value
``problem.true_value(theta)`` is recorded for reporting only. Duels are answered by the
preference oracle from the stored evaluation values; the optimizer only ever receives
``Outcome`` objects (winner id, loser id).

One record per evaluation with the columns of :data:`RESULT_COLUMNS`. ``best_seen`` and
``cumulative`` are the paper's metrics (App. D.1 table: best-seen ``f_best`` and cumulative
``sum_k f_k``) on true values. ``decision_seconds`` is the optimizer's own time in
``ask``/``tell`` (episodes and oracle excluded), split evenly over the candidates of an ask,
so the column sums to the optimizer's total time.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from localpbo_core.optimizers.base import Outcome
from localpbo_core.optimizers.preference_optimizer import PreferenceOptimizer
from localpbo_core.problems.base import Problem

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

#: Tag mixed into episode seeds: ``SeedSequence([run_seed, EPISODE_TAG, candidate_id])``.
EPISODE_TAG = 0xE915


class Oracle(Protocol):
    """A preference oracle: ``compare(a, b)`` is True iff the value ``a`` wins."""

    def compare(self, value_a: float, value_b: float) -> bool: ...


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


def episode_seed(run_seed: int, candidate_id: int) -> int:
    """The evaluation seed of a candidate, derived from the run seed and its id."""
    ss = np.random.SeedSequence([run_seed, EPISODE_TAG, candidate_id])
    return int(ss.generate_state(1, dtype=np.uint32)[0])


def run_loop(
    problem: Problem,
    optimizer: PreferenceOptimizer,
    oracle: Oracle,
    seed: int,
    algorithm: str | None = None,
    on_evaluation: Callable[[EvaluationRecord], None] | None = None,
) -> list[EvaluationRecord]:
    """Run ``optimizer`` on ``problem`` until its budget is spent.

    Args:
        problem: the task (its ``dim`` must equal the optimizer's).
        optimizer: a fresh ask/tell optimizer.
        oracle: answers duels from stored evaluation values.
        seed: run seed (episode seeds derive from it and the candidate id).
        algorithm: name written to the records (default ``optimizer.name``).
        on_evaluation: called with each record as soon as it is complete.

    Returns:
        one record per evaluation, in evaluation order.
    """
    if problem.dim != optimizer.dim:
        raise ValueError(f"dim: problem has d={problem.dim}, optimizer has d={optimizer.dim}")
    name = algorithm or optimizer.name
    values: dict[int, float] = {}
    records: list[EvaluationRecord] = []
    best = -np.inf
    cumulative = 0.0
    carry = 0.0  # optimizer time of asks without candidates, charged to the next candidates
    pending: list[tuple[int, float]] = []  # (candidate id, f_true) awaiting decision time
    while not optimizer.done:
        t0 = time.perf_counter()
        ask = optimizer.ask()
        decide = time.perf_counter() - t0
        for cand in ask.candidates:
            values[cand.id] = float(problem.evaluate(cand.theta, seed=episode_seed(seed, cand.id)))
            pending.append((cand.id, float(problem.true_value(cand.theta))))
        outcomes = []
        for duel in ask.duels:
            a, b = duel.first, duel.second
            a_wins = bool(oracle.compare(values[a], values[b]))
            outcomes.append(Outcome(a, b) if a_wins else Outcome(b, a))
        t0 = time.perf_counter()
        optimizer.tell(outcomes)
        decide += time.perf_counter() - t0 + carry
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
                algorithm=name,
                seed=seed,
                evaluation=len(records) + 1,
                candidate_id=cid,
                f_true=f_true,
                best_seen=float(best),
                cumulative=cumulative,
                decision_seconds=share,
            )
            records.append(rec)
            if on_evaluation is not None:
                on_evaluation(rec)
        pending = []
    return records
