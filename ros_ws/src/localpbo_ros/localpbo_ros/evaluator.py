"""The evaluator base: how a worker takes candidates, whatever it evaluates them on.

``sim_node`` (an episode of the task) and ``param_bridge_node`` (a trial on the user's node)
share one rule for the candidates on ``/localpbo/candidate``:

* before the run config is known a candidate is held (:meth:`FollowerNode.hold`);
* a candidate of another run, malformed, outside the task box, assigned to another worker
  (``candidates_for_others``) or with an id outside the run's range
  (:mod:`localpbo_ros.admission`) is dropped and counted;
* ids are idempotent: a known id with another θ is dropped (``dropped_conflicting_candidate``);
  a known id whose episode succeeded gets its stored result re-published
  (``results_repeated``, no second evaluation); one queued or under evaluation is counted
  (``candidates_repeated``); a failed one is evaluated again when published again (the
  optimizer's retry);
* while the worker refuses the run (:meth:`refusal_reason`) every candidate gets a ``failed``
  result;
* at most ``max_pending`` candidates wait (``dropped_buffer_full`` beyond).

Memory stays bounded under forged traffic: θ and results are kept per id of the run's range
only, the queue is bounded, and the held messages too.

Pool worker (:mod:`localpbo_ros.pool`): the worker announces its id (``<node name>.<8 hex>``)
and the candidate it evaluates in its status heartbeats (``info.worker``, ``info.busy``).

Subclasses evaluate from ``_queue`` (``_current`` is the candidate being evaluated) and report
with :meth:`_succeed` or :meth:`_fail`.
"""

from __future__ import annotations

from collections import deque
from typing import Unpack

from localpbo_msgs_py import CandidateMsg, EpisodeResult
from localpbo_msgs_py.topics import CANDIDATE, EPISODE_RESULT
from localpbo_ros.base import NodeOptions
from localpbo_ros.follower import FollowerNode
from localpbo_ros.params import Param
from localpbo_ros.pool import BUSY_INFO, WORKER_INFO, new_worker_id


class EvaluatorNode(FollowerNode):
    """A follower that evaluates the run's candidates (see module docstring).

    Args: as :class:`~localpbo_ros.follower.FollowerNode`.
    """

    def __init__(self, name: str, params: list[Param], **options: Unpack[NodeOptions]) -> None:
        super().__init__(name, params, **options)
        self._queue: deque[CandidateMsg] = deque()
        self._current: CandidateMsg | None = None
        self._thetas: dict[int, tuple[float, ...]] = {}
        self._results: dict[int, EpisodeResult] = {}
        self.worker_id = new_worker_id(self.get_name())
        self._pub = self.publisher(EPISODE_RESULT)
        self.subscribe(CANDIDATE, self._on_candidate)

    def status_info(self) -> dict[str, str]:
        """The worker id and the candidate being evaluated (empty when idle)."""
        busy = "" if self._current is None else str(self._current.candidate_id)
        return {WORKER_INFO: self.worker_id, BUSY_INFO: busy}

    def reset(self) -> None:
        """Forget the previous run's candidates, queue and results."""
        self._queue.clear()
        self._current = None
        self._thetas.clear()
        self._results.clear()

    def refusal_reason(self) -> str | None:
        """Why this worker refuses the run (every candidate fails with it); None to serve."""
        return None

    def queued(self) -> None:
        """Called after a candidate was appended to ``_queue`` (start work here if idle)."""

    # ------------------------------------------------------------------ candidates
    def _on_candidate(self, msg: object) -> None:
        if self.hold(self._on_candidate, msg):
            return
        cand = self.candidate_for(msg, self.worker_id)
        if cand is None:
            return
        cid = cand.candidate_id
        known = self._thetas.get(cid)
        if known is not None and known != cand.theta:
            self.drop("conflicting_candidate", f"candidate {cid} changed θ")
            return
        self._thetas[cid] = cand.theta
        cached = self._results.get(cid)
        refused = self.refusal_reason()
        if cached is not None:
            self.counters["results_repeated"] += 1
            self._pub.publish(cached.encode())
        elif refused is not None:
            self._fail(cand, refused)
        elif any(c.candidate_id == cid for c in self._queue) or (
            self._current is not None and self._current.candidate_id == cid
        ):
            self.counters["candidates_repeated"] += 1
        elif len(self._queue) >= self.settings["max_pending"]:
            self.drop("buffer_full", f"more than {self.settings['max_pending']} candidates waiting")
        else:
            self._queue.append(cand)
            self.queued()

    # ------------------------------------------------------------------ results
    def _succeed(self, cand: CandidateMsg, value: float) -> None:
        """Publish (and keep, for repeats) the return ``value`` of ``cand``."""
        assert self.config is not None
        result = EpisodeResult.ok(self.config.run_id, cand.candidate_id, value)
        self._results[cand.candidate_id] = result
        self.counters["episodes"] += 1
        self._pub.publish(result.encode())

    def _fail(self, cand: CandidateMsg, reason: str) -> None:
        """Publish a ``failed`` result of ``cand`` (not kept: a repeat evaluates again)."""
        assert self.config is not None
        self.counters["episodes_failed"] += 1
        self.warn("episode_failed", f"evaluation of candidate {cand.candidate_id} failed: {reason}")
        result = EpisodeResult.failed(
            self.config.run_id, cand.candidate_id, reason[:4000] or "error"
        )
        self._pub.publish(result.encode())
