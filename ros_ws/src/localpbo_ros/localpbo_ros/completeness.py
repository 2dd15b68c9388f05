"""Whether a bag holds everything the run published, and what each node last reported.

The optimizer knows what it published: its status carries the ids of the candidates and duel
requests it has published so far (``info.published_candidates``, ``info.published_duels``,
as id ranges such as ``0-29`` or ``0-12,15-20``; :class:`Published`). ``replay --verify``
compares them with the bag (:func:`missing_from_bag`), together with what the bag says about
itself: a recorded outcome needs its recorded request, a recorded request its two recorded
candidates. A message the run published that the bag lacks makes the verification fail,
naming it. Messages published after the optimizer's last recorded status (at most one status
period, 1 s) cannot be checked this way.

``bag-info`` prints the last status of every node of the run (:func:`last_statuses`): state,
counters (``dropped_<reason>`` among them) and info.
"""

from __future__ import annotations

import os
from collections.abc import Iterable

from localpbo_msgs_py import DecodeError, Status
from localpbo_msgs_py._validate import MAX_TEXT
from localpbo_msgs_py.bag import read_messages
from localpbo_msgs_py.topics import STATUS
from localpbo_ros.bagtools import RecordedRun
from localpbo_ros.base import NO_RUN

PUBLISHED_CANDIDATES = "published_candidates"
PUBLISHED_DUELS = "published_duels"
OMITTED = "+"
"""Leading mark of an id-range text whose earliest ranges were left out (too long)."""
SHOWN = 10
"""Missing ids named in a report (then ``...``)."""


def format_ids(ids: Iterable[int], limit: int = MAX_TEXT) -> str:
    """Ids as sorted ranges, ``0-12,15,17-20``; the earliest ranges are left out (and the text
    starts with ``+``) when it would be longer than ``limit`` characters."""
    ordered = sorted(set(ids))
    ranges: list[str] = []
    start = prev = None
    for i in ordered:
        if prev is not None and i == prev + 1:
            prev = i
            continue
        if start is not None:
            ranges.append(f"{start}" if start == prev else f"{start}-{prev}")
        start = prev = i
    if start is not None:
        ranges.append(f"{start}" if start == prev else f"{start}-{prev}")
    text = ",".join(ranges)
    while len(text) > limit and ranges:
        ranges.pop(0)
        text = OMITTED + ",".join(ranges)
    return text


def parse_ids(text: str) -> set[int]:
    """The ids of :func:`format_ids`' text (ranges left out are not known).

    Raises:
        ValueError: text that is not an id-range list.
    """
    ids: set[int] = set()
    body = text.removeprefix(OMITTED)
    for part in filter(None, body.split(",")):
        first, _, last = part.partition("-")
        lo, hi = int(first), int(last or first)
        if lo < 0 or hi < lo or hi - lo > 10**7:
            raise ValueError(f"bad id range {part!r}")
        ids.update(range(lo, hi + 1))
    return ids


class Published:
    """The ids a node has published, for its status (``info.published_*``)."""

    def __init__(self) -> None:
        self.candidates: set[int] = set()
        self.duels: set[int] = set()

    def candidate(self, candidate_id: int) -> None:
        """A candidate message went out."""
        self.candidates.add(candidate_id)

    def duel(self, duel_id: int) -> None:
        """A duel request went out."""
        self.duels.add(duel_id)

    def info(self) -> dict[str, str]:
        """The status info items."""
        return {
            PUBLISHED_CANDIDATES: format_ids(self.candidates),
            PUBLISHED_DUELS: format_ids(self.duels),
        }


def last_statuses(path: str | os.PathLike[str], run_id: str | None = None) -> dict[str, Status]:
    """The last recorded status of each node, by node name: of run ``run_id`` (or ``none``,
    a node before it knew the run) when given, else of any run."""
    last: dict[str, Status] = {}
    for rec in read_messages(path, topics=[STATUS.name]):
        status = Status.decode(rec.message)
        if isinstance(status, DecodeError):
            continue
        if run_id is not None and status.run_id not in (run_id, NO_RUN):
            continue
        known = last.get(status.node)
        if known is None or status.run_id != NO_RUN or known.run_id == NO_RUN:
            last[status.node] = status
    return last


def format_statuses(statuses: dict[str, Status]) -> list[str]:
    """``bag-info`` lines: each node's last state and counters, drops first."""
    if not statuses:
        return []
    lines = ["nodes (last status in the bag):"]
    width = max(len(n) for n in statuses)
    for node in sorted(statuses):
        s = statuses[node]
        drops = sorted((k, v) for k, v in s.counters.items() if k.startswith("dropped_"))
        rest = sorted((k, v) for k, v in s.counters.items() if not k.startswith("dropped_"))
        counters = ", ".join(f"{k} {v}" for k, v in drops + rest) or "no counters"
        lines.append(f"  {node:<{width}}  {s.state:<9} {counters}")
    return lines


def _shown(ids: Iterable[int]) -> str:
    ordered = sorted(ids)
    text = format_ids(ordered[:SHOWN])
    return text + (",..." if len(ordered) > SHOWN else "")


def missing_from_bag(path: str | os.PathLike[str], run: RecordedRun) -> str | None:
    """What the run published that the bag lacks (None: nothing found missing).

    Checks: every recorded outcome's duel has its request recorded, every recorded request
    its two candidates, and every id a recorded status of the run lists as published
    (:class:`Published`; a resumed run has one optimizer process per part) is recorded.
    """
    candidates = set(run.candidates)
    requests = set(run.requests)
    problems: list[str] = []
    published_c: set[int] = set()
    published_d: set[int] = set()
    for rec in read_messages(path, topics=[STATUS.name]):
        status = Status.decode(rec.message, expected_run_id=run.config.run_id)
        if isinstance(status, DecodeError) or PUBLISHED_CANDIDATES not in status.info:
            continue
        try:
            published_c |= parse_ids(status.info[PUBLISHED_CANDIDATES])
            published_d |= parse_ids(status.info.get(PUBLISHED_DUELS, ""))
        except ValueError as exc:
            problems.append(f"status of {status.node}: unreadable published ids ({exc})")
            break
    lost_d = published_d - requests
    if lost_d:
        problems.append(f"duel requests {_shown(lost_d)} were published but are not in the bag")
    lost_c = published_c - candidates
    if lost_c:
        problems.append(f"candidates {_shown(lost_c)} were published but are not in the bag")
    answered = {o.duel_id for o in run.outcomes} - requests - lost_d
    if answered:
        problems.append(f"duel requests {_shown(answered)} have outcomes but are not in the bag")
    named = {c for r in run.requests.values() for c in (r.first_id, r.second_id)}
    unnamed = named - candidates - lost_c
    if unnamed:
        problems.append(f"candidates {_shown(unnamed)} are in duel requests but not in the bag")
    return "; ".join(problems) or None
