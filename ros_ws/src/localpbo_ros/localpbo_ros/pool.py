"""A pool of evaluators: which worker evaluates which candidate (no ROS here).

Workers (``sim_node``, ``param_bridge_node``) announce themselves in their status heartbeats
(``info.worker=<worker id>``, ``info.busy=<candidate id>`` or empty). The optimizer node keeps a
:class:`WorkerPool`: it assigns each candidate still to evaluate to one live, idle worker (the
candidate message then carries ``worker=<id>``), frees the worker when the candidate's episode
result arrives, and takes a candidate back from a worker whose heartbeats stopped for
``timeout_s`` so another worker evaluates it. With no worker known, candidates go out
unassigned (anyone evaluates them: a single evaluator, or your own).

Who evaluates never changes a run: the episode seed depends only on the run seed and the
candidate id, so a duplicate result after a take-over is identical to the first (the oracle
keeps the first and counts the repeat).
"""

from __future__ import annotations

import secrets
from collections.abc import Iterable
from dataclasses import dataclass

from localpbo_msgs_py import Status

WORKER_INFO = "worker"
"""Status info key: the node's worker id (only evaluators that take assignments send it)."""
BUSY_INFO = "busy"
"""Status info key: the candidate id the worker is evaluating, empty when idle."""
SERVING_STATES = ("running",)
"""Worker states in which it takes candidates."""


def new_worker_id(node_name: str) -> str:
    """``<node name>.<8 hex digits>``: unique per node instance, across processes and hosts
    (two processes may both be named ``sim_node``)."""
    return f"{node_name[:54]}.{secrets.token_hex(4)}"


def worker_of(status: Status) -> str | None:
    """The worker id a status heartbeat announces (None: not a worker)."""
    return status.info.get(WORKER_INFO) or None


@dataclass
class Assignment:
    """One candidate out to one worker since ``since`` (monotonic seconds)."""

    candidate_id: int
    worker: str
    since: float


class WorkerPool:
    """Assignments of candidates to workers, from heartbeats and results.

    Args:
        timeout_s: a worker silent for this long is gone; its candidates are taken back.
        depth: candidates out to one worker at a time (more than one saves the round trip
            between a result and the next candidate; one spreads the work most evenly).
    """

    def __init__(self, timeout_s: float, depth: int = 1) -> None:
        self.timeout_s = timeout_s
        self.depth = depth
        self._seen: dict[str, float] = {}
        self._serving: dict[str, bool] = {}
        self._assigned: dict[int, Assignment] = {}
        self._done: dict[int, str] = {}
        self._failed: set[int] = set()
        self.assigned = 0
        self.reassigned = 0

    # ------------------------------------------------------------------ workers
    def heard(self, worker: str, serving: bool, now: float) -> bool:
        """A heartbeat of ``worker``; True if it is new (or back after being gone)."""
        new = not self.alive(worker, now)
        self._seen[worker] = now
        self._serving[worker] = serving
        return new

    def alive(self, worker: str, now: float) -> bool:
        """Heard within ``timeout_s``."""
        seen = self._seen.get(worker)
        return seen is not None and now - seen < self.timeout_s

    def live(self, now: float) -> list[str]:
        """Workers heard within ``timeout_s`` and taking candidates, by id."""
        return sorted(w for w in self._seen if self.alive(w, now) and self._serving[w])

    def load(self, now: float) -> dict[str, int]:
        """Live worker → its candidates out."""
        out = dict.fromkeys(self.live(now), 0)
        for a in self._assigned.values():
            if a.worker in out:
                out[a.worker] += 1
        return out

    def idle(self, now: float) -> list[str]:
        """Live workers without an assignment, by id."""
        return [w for w, n in self.load(now).items() if n == 0]

    # ------------------------------------------------------------------ candidates
    def worker_for(self, candidate_id: int) -> str:
        """The worker the candidate is (or was, once evaluated) assigned to; empty: none."""
        current = self._assigned.get(candidate_id)
        if current is not None:
            return current.worker
        return self._done.get(candidate_id, "")

    def assign(
        self, candidate_ids: Iterable[int], now: float, *, retry: bool = False
    ) -> list[Assignment]:
        """Assign the candidates not yet out or done (in id order) to live workers with room
        (fewer than ``depth`` out), each to the least loaded one (ties by id); those whose
        episode failed only with ``retry`` (the failure policy decides). The new
        assignments."""
        load = self.load(now)
        new: list[Assignment] = []
        for cid in sorted(set(candidate_ids)):
            room = [w for w, n in load.items() if n < self.depth]
            if not room:
                break
            if cid in self._assigned or cid in self._done or (cid in self._failed and not retry):
                continue
            self._failed.discard(cid)
            worker = min(room, key=lambda w: (load[w], w))
            load[worker] += 1
            a = Assignment(cid, worker, now)
            self._assigned[cid] = a
            self.assigned += 1
            new.append(a)
        return new

    def result(self, candidate_id: int, ok: bool) -> None:
        """The candidate's episode result arrived: its worker is free; an ok result makes the
        candidate done (never assigned again), a failed one waits for a retry."""
        a = self._assigned.pop(candidate_id, None)
        if not ok:
            if candidate_id not in self._done:
                self._failed.add(candidate_id)
        elif candidate_id not in self._done:
            self._failed.discard(candidate_id)
            self._done[candidate_id] = a.worker if a is not None else ""

    def expire(self, now: float) -> list[Assignment]:
        """Take back the candidates of workers gone silent or no longer serving (stopped,
        failed); the assignments taken back."""
        live = set(self.live(now))
        gone = [a for a in self._assigned.values() if a.worker not in live]
        for a in gone:
            del self._assigned[a.candidate_id]
            self.reassigned += 1
        return gone

    def outstanding(self) -> dict[int, str]:
        """Candidate id → worker of the assignments without a result yet."""
        return {cid: a.worker for cid, a in self._assigned.items()}

    def clear_candidates(self) -> None:
        """Forget assignments and results (a new run)."""
        self._assigned.clear()
        self._done.clear()
        self._failed.clear()
