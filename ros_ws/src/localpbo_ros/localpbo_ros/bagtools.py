"""Reading a recorded run back from its bag (for ``replay --verify`` and ``run --resume``)."""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np

from localpbo_core.problems.registry import replayed_problem_options
from localpbo_msgs_py import CandidateMsg, DuelOutcome, DuelRequest, OutcomeKind, RunConfig
from localpbo_msgs_py.bag import BagWriter, read_messages, summarize
from localpbo_msgs_py.topics import ALL_TOPICS, CANDIDATE, DUEL_OUTCOME, DUEL_REQUEST, RUN_CONFIG


@dataclass(frozen=True)
class RecordedRun:
    """What a bag says about one run.

    Attributes:
        config: the run config (the file alone says how the run was made).
        candidates: first recorded message of each candidate id.
        requests: first recorded request of each duel id.
        outcomes: every decodable outcome of this run, in recorded order (the optimizer's
            acceptance rule is applied when they are re-fed, see ``driver.rebuild``).
        complete: the file has its footer (the recorder was closed, not killed).
    """

    config: RunConfig
    candidates: dict[int, CandidateMsg]
    requests: dict[int, DuelRequest]
    outcomes: tuple[DuelOutcome, ...]
    complete: bool


def same_run_config(a: RunConfig, b: RunConfig) -> bool:
    """Whether two run configs describe the same run: equal, or equal once a MuJoCo task's
    noise scale is made explicit (a bag resumed from one recorded before run configs named
    the task's ``value_range`` holds the old config and the resumed run's explicit one)."""

    def canonical(c: RunConfig) -> str:
        task = c.options.get("task")
        if not isinstance(task, dict):
            return c.to_json()
        options = {**c.options, "task": replayed_problem_options(c.task, task)}
        return replace(c, options=options).to_json()

    return a.to_json() == b.to_json() or canonical(a) == canonical(b)


def load_run(path: str | os.PathLike[str]) -> RecordedRun:
    """Decode the run recorded in ``path`` (finished or cut off by a crash).

    Raises:
        ValueError: no valid run config, or configs of two different runs in one bag.
    """
    config: RunConfig | None = None
    for rec in read_messages(path, topics=[RUN_CONFIG.name]):
        decoded = RunConfig.decode(rec.message)
        if not isinstance(decoded, RunConfig):
            continue
        if config is None:
            config = decoded
        elif not same_run_config(decoded, config):
            raise ValueError(
                f"{path}: holds run configs of two runs ({config.run_id!r}, {decoded.run_id!r})"
            )
    if config is None:
        raise ValueError(f"{path}: no valid {RUN_CONFIG.name} message; not a localpbo run bag")
    candidates: dict[int, CandidateMsg] = {}
    requests: dict[int, DuelRequest] = {}
    outcomes: list[DuelOutcome] = []
    wanted = [CANDIDATE.name, DUEL_REQUEST.name, DUEL_OUTCOME.name]
    for rec in read_messages(path, topics=wanted):
        if rec.topic == CANDIDATE.name:
            cand = CandidateMsg.decode(
                rec.message, expected_run_id=config.run_id, expected_dim=config.dim
            )
            if isinstance(cand, CandidateMsg):
                candidates.setdefault(cand.candidate_id, cand)
        elif rec.topic == DUEL_REQUEST.name:
            req = DuelRequest.decode(rec.message, expected_run_id=config.run_id)
            if isinstance(req, DuelRequest):
                requests.setdefault(req.duel_id, req)
        else:
            out = DuelOutcome.decode(rec.message, expected_run_id=config.run_id)
            if isinstance(out, DuelOutcome):
                outcomes.append(out)
    return RecordedRun(config, candidates, requests, tuple(outcomes), summarize(path).complete)


def copy_into(path: str | os.PathLike[str], writer: BagWriter) -> int:
    """Append every message of ``path`` to ``writer`` with its original times; returns count."""
    writer.add_suite_topics(ALL_TOPICS)
    n = 0
    for rec in read_messages(path):
        writer.write(
            rec.topic, rec.message, log_time_ns=rec.log_time_ns, publish_time_ns=rec.publish_time_ns
        )
        n += 1
    return n


@dataclass(frozen=True)
class Timing:
    """Count, median, 95th percentile and maximum of per-duel durations (seconds), shown in
    ``unit`` (``ms`` or ``s``)."""

    name: str
    seconds: tuple[float, ...]
    unit: str = "ms"

    def format(self) -> str:
        """One line, e.g. ``decision time: 40 duels, median 12.3 ms, p95 150 ms, max 180 ms``."""
        if not self.seconds:
            return f"{self.name}: not recorded"
        u = self.unit
        x = np.asarray(self.seconds) * {"ms": 1e3, "s": 1.0}[u]
        return (
            f"{self.name}: {len(x)} duels, median {np.median(x):.3g} {u}, "
            f"p95 {np.percentile(x, 95):.3g} {u}, max {x.max():.3g} {u}"
        )


@dataclass(frozen=True)
class OutcomeCounts:
    """How the duels of a run ended, each duel counted once (its first recorded outcome;
    an outcome re-published for a repeated request is the same answer)."""

    decisive: int
    indifferent: int
    failed: int

    @property
    def duels(self) -> int:
        """Duels with an outcome."""
        return self.decisive + self.indifferent + self.failed

    def format(self) -> str:
        """One line, e.g. ``outcomes: 40 duels, 31 decisive, 9 can't tell, 0 failed``."""
        return (
            f"outcomes: {self.duels} duels, {self.decisive} decisive, "
            f"{self.indifferent} can't tell, {self.failed} failed"
        )


def outcome_counts(run: RecordedRun) -> OutcomeCounts:
    """Count the outcomes of a recorded run (:func:`load_run`) by kind, one per duel."""
    first: dict[int, OutcomeKind] = {}
    for out in run.outcomes:
        first.setdefault(out.duel_id, out.kind)
    kinds = list(first.values())
    return OutcomeCounts(
        decisive=kinds.count(OutcomeKind.DECISIVE),
        indifferent=kinds.count(OutcomeKind.INDIFFERENT),
        failed=kinds.count(OutcomeKind.FAILED),
    )


def duel_timings(run: RecordedRun) -> Sequence[Timing]:
    """Per-duel times of a recorded run (:func:`load_run`): the optimizer's decision time (from the
    ``decision_seconds`` of each duel's first request) and, when a person judged
    (``judge_node``), the answer time (``answer_seconds`` of each duel's first timed outcome;
    an answer re-published for a repeated request counts once)."""
    decision = tuple(
        r.decision_seconds
        for _, r in sorted(run.requests.items())
        if r.decision_seconds is not None
    )
    answers: dict[int, float] = {}
    for out in run.outcomes:
        if out.answer_seconds is not None:
            answers.setdefault(out.duel_id, out.answer_seconds)
    timings = [Timing("decision time", decision)]
    if answers:
        timings.append(Timing("answer time", tuple(answers[k] for k in sorted(answers)), "s"))
    return tuple(timings)
