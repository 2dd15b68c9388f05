"""Reading a recorded run back from its bag (for ``replay --verify``, ``run --resume`` and
``bag-info``).

A bag belongs to the run of its run config: candidates, duel requests and outcomes of another
run id on the run's own topics, or candidates whose θ the config's task cannot hold (another
dimension, outside its bounds), mean the config was edited or the messages come from another
run; :func:`history_problem` names the field (or the foreign run) and ``--verify`` and
``--resume`` refuse such a bag. A file that is not MCAP at all is refused by
:func:`require_bag`; a file that ends early (cut inside a record) is read up to its last whole
record and says so (:attr:`RecordedRun.ends_early`).
"""

from __future__ import annotations

import os
from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass, field, replace

import numpy as np

from localpbo_core.problems.registry import replayed_problem_options
from localpbo_msgs_py import (
    CandidateMsg,
    DecodeError,
    DuelOutcome,
    DuelRequest,
    OutcomeKind,
    RunConfig,
    Status,
)
from localpbo_msgs_py.bag import BagSummary, BagWriter, read_messages, summarize
from localpbo_msgs_py.topics import (
    ALL_TOPICS,
    CANDIDATE,
    DUEL_OUTCOME,
    DUEL_REQUEST,
    RUN_CONFIG,
    STATUS,
)

MCAP_MAGIC = b"\x89MCAP0\r\n"
"""The first bytes of every MCAP file."""
OPTIMIZER_STATUS_NAMES = ("optimizer_node", "optimizer")
"""The optimizer's name in its status messages (``optimizer`` in bags of earlier versions);
a renamed optimizer is known by its ``duels_done`` counter."""


class NotABagError(ValueError):
    """The file is not an MCAP bag (no MCAP magic at its start)."""


def require_bag(path: str | os.PathLike[str]) -> None:
    """Refuse a file that is not an MCAP bag before anything reads it as one.

    Raises:
        OSError: the file cannot be read.
        NotABagError: ``<path>: not an MCAP bag (...)``.
    """
    with open(path, "rb") as stream:
        head = stream.read(len(MCAP_MAGIC))
    if head != MCAP_MAGIC:
        what = "empty file" if not head else f"starts with {head[:8]!r}"
        raise NotABagError(f"{path}: not an MCAP bag ({what}, not the MCAP magic)")


def ends_early(summary: BagSummary) -> str:
    """What was read and where the file ends, for a file cut inside a record (a copy cut
    short, a full disk: the messages of its last, partial chunk are lost); empty for a whole
    file, also one whose writer was killed (no footer, but everything written is read)."""
    if summary.complete or summary.whole_bytes is None:
        return ""
    if summary.whole_bytes >= summary.size_bytes:
        return ""
    return (
        f"the file ends early: cut inside a record at byte {summary.whole_bytes} of "
        f"{summary.size_bytes} ({summary.message_count} messages readable before it)"
    )


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
        foreign: decodable candidates, requests and outcomes of other runs on the run's
            topics, by run id (a bag whose messages are not its config's run).
        unfit: candidates of this run the config's task cannot hold, by reason
            (``wrong_shape``, ``out_of_bounds``), with the first one's text.
        optimizer_state: the last state the run's optimizer reported (``done`` once the
            run finished; empty when no status was recorded).
        ends_early: what :func:`ends_early` says about the file (empty when it is whole).
    """

    config: RunConfig
    candidates: dict[int, CandidateMsg]
    requests: dict[int, DuelRequest]
    outcomes: tuple[DuelOutcome, ...]
    complete: bool
    foreign: dict[str, int] = field(default_factory=dict)
    unfit: dict[str, tuple[int, str]] = field(default_factory=dict)
    optimizer_state: str = ""
    ends_early: str = ""

    @property
    def finished(self) -> str:
        """Whether the run finished (its optimizer reported ``done``), e.g. ``yes (40 of 40
        evaluations)`` or ``no: stopped at 346 of 1000 evaluations (optimizer running)``
        (``unknown`` without the optimizer's status); independent of whether the file is
        complete."""
        used = f"{len(self.candidates)} of {self.config.budget} evaluations"
        if self.optimizer_state == "done":
            return f"yes ({used})"
        if not self.optimizer_state:
            return f"unknown: no optimizer status recorded ({used})"
        return f"no: stopped at {used} (optimizer {self.optimizer_state})"


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
        NotABagError: not an MCAP file.
        ValueError: no valid run config, or configs of two different runs in one bag.
    """
    require_bag(path)
    config: RunConfig | None = None
    for rec in read_messages(path, topics=[RUN_CONFIG.name]):
        found = RunConfig.decode(rec.message)
        if not isinstance(found, RunConfig):
            continue
        if config is None:
            config = found
        elif not same_run_config(found, config):
            raise ValueError(
                f"{path}: holds run configs of two runs ({config.run_id!r}, {found.run_id!r})"
            )
    if config is None:
        raise ValueError(f"{path}: no valid {RUN_CONFIG.name} message; not a localpbo run bag")
    candidates: dict[int, CandidateMsg] = {}
    requests: dict[int, DuelRequest] = {}
    outcomes: list[DuelOutcome] = []
    foreign: Counter[str] = Counter()
    unfit: dict[str, tuple[int, str]] = {}
    state = ""
    wanted = [CANDIDATE.name, DUEL_REQUEST.name, DUEL_OUTCOME.name, STATUS.name]
    for rec in read_messages(path, topics=wanted):
        if rec.topic == STATUS.name:
            status = Status.decode(rec.message)
            if (
                isinstance(status, Status)
                and status.run_id == config.run_id
                and (status.node in OPTIMIZER_STATUS_NAMES or "duels_done" in status.counters)
            ):
                state = status.state
            continue
        decoded: CandidateMsg | DuelRequest | DuelOutcome | DecodeError
        if rec.topic == CANDIDATE.name:
            decoded = CandidateMsg.decode(rec.message)
        elif rec.topic == DUEL_REQUEST.name:
            decoded = DuelRequest.decode(rec.message)
        else:
            decoded = DuelOutcome.decode(rec.message)
        if isinstance(decoded, DecodeError):
            continue  # malformed: no run to count it for
        if decoded.run_id != config.run_id:
            foreign[decoded.run_id] += 1
        elif isinstance(decoded, CandidateMsg):
            fit = CandidateMsg.decode(
                rec.message,
                expected_run_id=config.run_id,
                expected_dim=config.dim,
                lower=config.lower,
                upper=config.upper,
            )
            if isinstance(fit, DecodeError):
                count, first = unfit.get(fit.reason.value, (0, ""))
                text = first or f"candidate {decoded.candidate_id}: {fit.problem}"
                unfit[fit.reason.value] = (count + 1, text)
            else:
                candidates.setdefault(fit.candidate_id, fit)
        elif isinstance(decoded, DuelRequest):
            requests.setdefault(decoded.duel_id, decoded)
        else:
            outcomes.append(decoded)
    summary = summarize(path)
    return RecordedRun(
        config,
        candidates,
        requests,
        tuple(outcomes),
        summary.complete,
        dict(foreign),
        unfit,
        state,
        ends_early(summary),
    )


def history_problem(run: RecordedRun) -> str:
    """Why the recorded messages cannot be this config's run (empty when nothing says so):
    messages of another run, candidates the config's task cannot hold, more candidates than
    the config's budget, or a finished run that spent fewer evaluations than the budget.
    The rebuild (``replay.verify``) checks the rest: the seed, algorithm and options."""
    config = run.config
    if run.foreign:
        runs = ", ".join(f"{rid!r} ({n})" for rid, n in sorted(run.foreign.items())[:5])
        own = len(run.candidates) + len(run.requests) + len(run.outcomes)
        return (
            f"holds messages of another run: {runs} on the run's topics, beside {own} of run "
            f"{config.run_id!r}, whose run config it holds; the bag is not one run's record"
        )
    if run.unfit:
        count = sum(n for n, _ in run.unfit.values())
        first = next(text for _, text in run.unfit.values())
        return (
            f"field task: {count} recorded candidate(s) do not fit the run config's task "
            f"{config.task!r} (dimension {config.dim}, its bounds), e.g. {first}"
        )
    # a person's undo discards candidates whose ids stay spent: then more ids than the budget
    undone = any(o.kind is OutcomeKind.RETRACTED for o in run.outcomes)
    beyond = sorted(cid for cid in run.candidates if cid >= config.budget)
    if beyond and not undone:
        return (
            f"field budget: candidate {beyond[0]} is recorded ({len(run.candidates)} "
            f"candidates in all) but the run config's budget is {config.budget}"
        )
    if run.optimizer_state == "done" and len(run.candidates) < config.budget:
        return (
            f"field budget: the recorded run finished after {len(run.candidates)} evaluations "
            f"but the run config's budget is {config.budget}"
        )
    return ""


def copy_into(path: str | os.PathLike[str], writer: BagWriter) -> int:
    """Append every message of ``path`` to ``writer`` with its original times; returns count."""
    writer.add_suite_topics(ALL_TOPICS)
    n = 0
    for rec in read_messages(path):
        writer.copy(rec)
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


def judged_by(run: RecordedRun) -> str:
    """One line on who gave the answers that stand (each duel's answer, a re-published one
    counted once, a taken-back one not at all) and how many carry a note, e.g. ``judged by:
    Ada 31, Bo 9; 4 notes``; empty when no answer names a person."""
    first: dict[int, DuelOutcome] = {}
    for out in run.outcomes:
        if out.kind is OutcomeKind.RETRACTED:
            first.pop(out.duel_id, None)
        elif out.kind in (OutcomeKind.DECISIVE, OutcomeKind.INDIFFERENT):
            first.setdefault(out.duel_id, out)
    people = Counter(out.judge for out in first.values() if out.judge)
    if not people:
        return ""
    notes = sum(1 for out in first.values() if out.note)
    names = ", ".join(f"{name} {n}" for name, n in sorted(people.items()))
    return f"judged by: {names}; {notes} note{'' if notes == 1 else 's'}"


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
