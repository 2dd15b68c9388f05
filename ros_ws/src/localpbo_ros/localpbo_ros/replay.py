"""``localpbo replay BAG``: re-publish a bag like ``ros2 bag play``, or verify it offline.

Play: every recorded message (optionally only ``topics``) is published at its original
offset from the first message divided by ``rate``, ``loops`` times; each topic's publisher uses
the QoS recorded in the channel's ``offered_qos_profiles`` metadata, so latched topics stay
latched; without it, reliable/volatile/depth 10 as rosbag2 does.

Verify: rebuild the run from the recorded run config, re-feed the recorded outcomes with the
node's own acceptance rule (the run protocol of ``localpbo_core.session``: same config and
outcomes give the same candidates), and check that it proposes exactly the recorded
candidates (θ compared as decoded floats, never as CDR bytes) and duels. Before the rebuild,
a bag whose messages cannot be its config's run is refused naming the field or the foreign
run (``bagtools.history_problem``); a file that is not MCAP is refused as such, one that
ends early is checked as far as it reads and says so. :func:`resumable` is the same check
for ``run --resume``. Verify also fails when the bag lacks a message the run published
(:func:`localpbo_ros.completeness.missing_from_bag`), naming it. When a rebuilt candidate or
duel parts from the recorded one, the report says why it may: where the bag's
``localpbo/platform`` record (CPU and flags, library versions, code digest) differs from
here, the other platform or code; otherwise an edited run config.
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass, replace
from typing import Any

from rclpy.duration import Duration
from rclpy.executors import Executor
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

from localpbo_core.provenance import recorded_elsewhere
from localpbo_msgs_py.bag import message_class, read_messages, summarize
from localpbo_msgs_py.qos_yaml import parse_offered_qos
from localpbo_ros.bagtools import RecordedRun, history_problem, load_run, require_bag
from localpbo_ros.completeness import missing_from_bag
from localpbo_ros.driver import rebuild

_HISTORY = {"keep_last": HistoryPolicy.KEEP_LAST, "keep_all": HistoryPolicy.KEEP_ALL}
_RELIABILITY = {
    "reliable": ReliabilityPolicy.RELIABLE,
    "best_effort": ReliabilityPolicy.BEST_EFFORT,
}
_DURABILITY = {
    "volatile": DurabilityPolicy.VOLATILE,
    "transient_local": DurabilityPolicy.TRANSIENT_LOCAL,
}
INFINITE_SEC = 9223372036


def qos_from_metadata(text: str) -> QoSProfile:
    """The playback QoS of a channel from its ``offered_qos_profiles`` YAML.

    With several offered profiles the most permissive compatible choice is made as rosbag2
    does: reliable only if all publishers were reliable, transient-local only if all were.
    """
    profiles = parse_offered_qos(text)
    if not profiles:
        return QoSProfile(
            depth=10, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.VOLATILE
        )
    reliable = all(p.get("reliability") == "reliable" for p in profiles)
    durable = all(p.get("durability") == "transient_local" for p in profiles)
    first = profiles[0]
    qos = QoSProfile(
        history=_HISTORY.get(first.get("history", "keep_last"), HistoryPolicy.KEEP_LAST),
        depth=max(int(first.get("depth", 10)), 1),
        reliability=ReliabilityPolicy.RELIABLE if reliable else ReliabilityPolicy.BEST_EFFORT,
        durability=DurabilityPolicy.TRANSIENT_LOCAL if durable else DurabilityPolicy.VOLATILE,
    )
    deadline = first.get("deadline", {})
    if deadline and deadline.get("sec", INFINITE_SEC) < INFINITE_SEC:
        qos.deadline = Duration(seconds=deadline["sec"], nanoseconds=deadline.get("nsec", 0))
    return qos


def play(
    path: str | os.PathLike[str],
    node: Node,
    executor: Executor,
    *,
    rate: float = 1.0,
    loops: int = 1,
    topics: Iterable[str] | None = None,
    should_stop: Callable[[], bool] = lambda: False,
) -> int:
    """Publish the bag's messages from ``node`` with their original timing; returns count.

    ``loops`` passes over the bag (0: until ``should_stop`` or Ctrl-C). ``executor`` is spun
    while waiting (so in-process subscribers get the messages).
    """
    if not rate > 0:
        raise ValueError(f"rate: must be > 0, got {rate}")
    if loops < 0:
        raise ValueError(f"loop: must be >= 0, got {loops}")
    require_bag(path)
    summary = summarize(path)
    wanted = None if topics is None else set(topics)
    known = {t.topic for t in summary.topics}
    if wanted is not None and not wanted <= known:
        raise ValueError(f"topics: not in the bag: {sorted(wanted - known)}")
    publishers: dict[str, Any] = {}
    for t in summary.topics:
        if wanted is None or t.topic in wanted:
            publishers[t.topic] = node.create_publisher(
                message_class(t.type_name), t.topic, qos_from_metadata(t.offered_qos_profiles)
            )
    sent = 0
    done_loops = 0
    while loops == 0 or done_loops < loops:
        done_loops += 1
        t0_bag: int | None = None
        t0_wall = time.monotonic()
        for rec in read_messages(path, topics=publishers.keys()):
            if t0_bag is None:
                t0_bag = rec.log_time_ns
            due = t0_wall + (rec.log_time_ns - t0_bag) / 1e9 / rate
            while True:
                left = due - time.monotonic()
                if left <= 0 or should_stop():
                    break
                executor.spin_once(timeout_sec=min(left, 0.05))
            if should_stop():
                return sent
            publishers[rec.topic].publish(rec.message)
            sent += 1
    return sent


@dataclass(frozen=True)
class VerifyReport:
    """Result of :func:`verify`."""

    ok: bool
    candidates_checked: int
    duels_checked: int
    outcomes_used: int
    unpublished: int
    mismatch: str
    ends_early: str = ""
    """What ``bagtools.ends_early`` says of the file (empty: it is whole or unfinished)."""

    def format(self) -> str:
        """``OK ...`` or ``MISMATCH ...`` (and a note when the file ends early)."""
        note = f"\nnote: {self.ends_early}; checked what was read" if self.ends_early else ""
        return self._verdict() + note

    def _verdict(self) -> str:
        if self.ok:
            extra = (
                (
                    f"; {self.unpublished} proposed candidate(s) were not recorded (run "
                    "stopped before publishing them)"
                )
                if self.unpublished
                else ""
            )
            return (
                f"OK: {self.candidates_checked} candidates and {self.duels_checked} duels "
                f"reproduced from {self.outcomes_used} recorded outcomes{extra}"
            )
        return f"MISMATCH: {self.mismatch}"


def verify(path: str | os.PathLike[str]) -> VerifyReport:
    """Rebuild the optimizer offline and compare with the recorded candidates and duels.

    Raises:
        OSError: the file cannot be read.
        ValueError: not an MCAP bag (``bagtools.NotABagError``), or no run config in it.
    """
    run = load_run(path)
    report = check_run(run, path)
    gap = missing_from_bag(path, run)  # what the run published that the bag lacks
    if gap is None:
        return report
    also = "" if report.ok else f" (and: {report.mismatch})"
    return replace(report, ok=False, mismatch=f"{path}: {gap}{also}")


def check_run(run: RecordedRun, path: str | os.PathLike[str]) -> VerifyReport:
    """:func:`verify` of an already loaded run."""
    problem = history_problem(run)
    if problem:
        return VerifyReport(False, 0, 0, 0, 0, f"{path}: {problem}", run.ends_early)
    return replace(_compare(run, lambda: _elsewhere(path)), ends_early=run.ends_early)


def _elsewhere(path: str | os.PathLike[str]) -> list[str] | None:
    """What differs between where the bag was recorded and here (its ``localpbo/platform``
    record against :func:`localpbo_core.provenance.recording_platform`); None when the bag
    does not say."""
    recorded = summarize(path).platform
    return recorded_elsewhere(recorded) if recorded else None


def _cause(elsewhere: list[str] | None) -> str:
    """Why a rebuilt run can part from the recorded one."""
    if elsewhere:
        return (
            f"the bag was recorded on another platform or by other code ({'; '.join(elsewhere)}"
            "): the same run config and outcomes re-make a model-based run bit for bit only "
            "with the same code on the same platform"
        )
    config = (
        "the run config's seed, algorithm or their options are not the recorded run's: "
        "fields seed, algorithm, algorithm_options, initial_design"
    )
    if elsewhere is None:
        return (
            f"{config}; or the run was recorded on another platform or by other code (the bag "
            "has no localpbo/platform record to tell)"
        )
    return config


def resumable(path: str | os.PathLike[str]) -> RecordedRun:
    """The run recorded in ``path`` if ``run --resume`` may continue it: its messages are
    its config's run and the config rebuilds them (:func:`verify` says OK).

    Raises:
        OSError: the file cannot be read.
        ValueError: the reason, naming the file and the field or foreign run.
    """
    run = load_run(path)
    report = check_run(run, path)
    if not report.ok:
        detail = report.mismatch
        if not detail.startswith(str(path)):
            detail = (
                f"{path}: its history does not follow from its run config ({detail}); "
                "`localpbo replay --verify` shows the same"
            )
        raise ValueError(detail)
    return run


def _compare(run: RecordedRun, elsewhere: Callable[[], list[str] | None]) -> VerifyReport:
    rebuilt = rebuild(run.config, run.outcomes)
    proposed = {c.candidate_id: c for c in rebuilt.proposed}
    used = rebuilt.driver.n_duels
    for cid in sorted(run.candidates):
        rec = run.candidates[cid]
        mine = proposed.get(cid)
        if mine is None:
            return VerifyReport(
                False, 0, 0, used, 0, f"candidate {cid} is recorded but was not proposed"
            )
        if mine.theta != rec.theta:
            diff = next(
                i for i, (a, b) in enumerate(zip(mine.theta, rec.theta, strict=True)) if a != b
            )
            return VerifyReport(
                False,
                0,
                0,
                used,
                0,
                f"candidate {cid}: θ[{diff}] recorded {rec.theta[diff]!r}, "
                f"rebuilt {mine.theta[diff]!r}, a gap of "
                f"{abs(rec.theta[diff] - mine.theta[diff]):.3g} ({_cause(elsewhere())})",
            )
    duels = {r.duel_id: r for r in rebuilt.requests}
    for did in sorted(run.requests):
        req = run.requests[did]
        ours = duels.get(did)
        if ours is None or (ours.first_id, ours.second_id) != (req.first_id, req.second_id):
            mine_txt = "none" if ours is None else f"{ours.first_id} vs {ours.second_id}"
            return VerifyReport(
                False,
                0,
                0,
                used,
                0,
                f"duel {did}: recorded {req.first_id} vs {req.second_id}, rebuilt {mine_txt} "
                f"({_cause(elsewhere())})",
            )
    unpublished = len(set(proposed) - set(run.candidates))
    return VerifyReport(True, len(run.candidates), len(run.requests), used, unpublished, "")
