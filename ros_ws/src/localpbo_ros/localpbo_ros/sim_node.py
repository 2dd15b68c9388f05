"""``sim_node``: runs one episode per candidate and publishes its return.

Subscribes ``/localpbo/run_config`` and ``/localpbo/candidate``; publishes
``/localpbo/episode_result`` and ``/localpbo/status``. θ arrives in task units and is evaluated
as received (``evaluate_native``) with the candidate's episode seed
(``localpbo_core.seeds.episode_seed(run seed, candidate id)``): exactly what the in-process
run evaluates, whichever process evaluates it and in whichever order.

Candidates are taken as every evaluator takes them (:mod:`localpbo_ros.evaluator`: held
until the run config, ids within the run's range, idempotent by id, a bounded queue): a
candidate seen again with the same θ gets its stored result re-published (no second episode);
a failed episode is re-run when its candidate is published again (retry). An evaluator that
raises, or returns a non-finite value, yields a ``failed`` episode result.

Ahead of time (``/localpbo/speculative_candidate``, published by an optimizer that
speculates): a candidate the next ask may propose is evaluated while the current duel is
judged and its return kept (at most ``AHEAD_KEPT``, by id and θ); when the real candidate
arrives with the same id and θ, that return is published at once (``episodes_ahead_used``) —
the number the episode would give now, since it is a function of run seed, id and θ. An
episode ahead that fails or is never asked for leaves no trace. At most ``AHEAD_PER_ID``
episodes run ahead per id of the run's range (forged speculative candidates are bounded too).
Episodes ahead are handed by a thread of their own to a worker process
(:mod:`localpbo_ros.episode_process`; an evaluator given to the node is called in that thread,
under a lock), so neither the executor nor the interpreter lock is held by them while a
person's answer to the open duel arrives; a real candidate whose episode ahead is under way
waits for it rather than running it a second time.

Pool worker (:mod:`localpbo_ros.pool`): the node announces its worker id
(``<node name>.<8 hex>``) and the candidate it evaluates in its status heartbeats
(``info.worker``, ``info.busy``; one heartbeat also goes out as an episode starts). It
evaluates the candidates assigned to it (``worker=<its id>``) and unassigned ones, and skips
those assigned to another worker (``candidates_for_others``). The node evaluates in its
executor's thread, so it sends no heartbeat during an episode: the optimizer's
``worker_timeout_s`` must exceed the longest episode. A worker that stops on a signal reports
state ``stopped`` on its way out, and its candidate goes to another worker at once.
"""

from __future__ import annotations

import math
import threading
from collections import Counter, OrderedDict, deque
from collections.abc import Callable
from typing import Any, NoReturn, Unpack

import numpy as np

from localpbo_core.seeds import episode_seed
from localpbo_core.session import evaluate_native
from localpbo_msgs_py import RunConfig
from localpbo_msgs_py.topics import SPECULATIVE_CANDIDATE
from localpbo_ros.base import NodeOptions
from localpbo_ros.driver import judged_by_person, problem_of
from localpbo_ros.episode_process import EpisodeProcess
from localpbo_ros.evaluator import EvaluatorNode

AHEAD_KEPT = 16
"""Returns of episodes run ahead kept (oldest dropped), and episodes ahead waiting to run at
most (more are dropped: ``dropped_ahead_queue_full``)."""
AHEAD_PER_ID = 4
"""Episodes run ahead per candidate id (one per possible answer: A, B, can't tell); more are
dropped (``dropped_ahead_limit``), so forged speculative candidates cost a bounded number of
episodes per id of the run's range."""

Evaluator = Callable[[RunConfig, int, np.ndarray], float]
"""``(run config, candidate id, θ in task units as received) -> episode return``."""


class SimNode(EvaluatorNode):
    """The simulator node (see module docstring).

    Args:
        evaluator: replaces the task's own episode (tests, your own simulator).
    """

    def __init__(
        self,
        *,
        evaluator: Evaluator | None = None,
        **options: Unpack[NodeOptions],
    ) -> None:
        super().__init__("sim_node", [], **options)
        self._evaluator = evaluator
        self._evaluator_lock = threading.Lock()  # a given evaluator: one call at a time
        self._problem: Any = None
        self._episodes = EpisodeProcess()  # started by the first episode ahead
        # guarded by _ahead_cond: episodes ahead waiting, the one running, the returns kept
        self._ahead_cond = threading.Condition()
        self._ahead_todo: deque[tuple[int, RunConfig, int, tuple[float, ...]]] = deque()
        self._ahead_running: tuple[int, tuple[float, ...]] | None = None
        self._ahead: OrderedDict[tuple[int, tuple[float, ...]], float] = OrderedDict()
        self._ahead_generation = 0  # a reset makes the worker's episode under way stale
        self._ahead_stop = False
        self._ahead_runs: Counter[int] = Counter()  # episodes run ahead per candidate id
        self._ahead_thread = threading.Thread(
            target=self._run_ahead, name="sim-episodes-ahead", daemon=True
        )
        self._ahead_thread.start()
        self.subscribe(SPECULATIVE_CANDIDATE, self._on_speculative)
        self.publish_status()  # announce the worker now, not a status period later

    @property
    def busy(self) -> int | None:
        """The candidate being evaluated (None when idle)."""
        return None if self._current is None else self._current.candidate_id

    def close(self) -> None:
        """Stopping (SIGINT/SIGTERM): say so, so the optimizer hands this worker's candidate
        to another worker at once instead of after ``worker_timeout_s``."""
        self.state = "stopped"
        self.publish_status()

    def destroy_node(self) -> None:
        """Stop the worker thread of the episodes ahead (an episode under way is finished)."""
        with self._ahead_cond:
            self._ahead_stop = True
            self._ahead_todo.clear()
            self._ahead_cond.notify_all()
        self._ahead_thread.join(timeout=5.0)
        self._episodes.close()
        super().destroy_node()

    def reset(self) -> None:
        """Forget the previous run, its episodes run ahead too."""
        super().reset()
        with self._ahead_cond:
            self._ahead_generation += 1
            self._ahead_todo.clear()
            self._ahead.clear()
            self._ahead_cond.notify_all()
        self._ahead_runs.clear()

    def adopt(self, config: RunConfig) -> None:
        """Build the task of the run (unless an evaluator was given); a run a person judges
        starts the process of the episodes ahead now."""
        if self._evaluator is None:
            self._problem = problem_of(config)
            if self._problem.dim != config.dim:
                raise ValueError(f"dim: task has {self._problem.dim}, config {config.dim}")
            if judged_by_person(config):  # the optimizer will speculate: episodes ahead
                self._episodes.warm(config)

    def _evaluate(self, config: RunConfig, cid: int, native: tuple[float, ...]) -> float:
        if self._evaluator is not None:
            with self._evaluator_lock:
                return float(self._evaluator(config, cid, np.asarray(native, dtype=np.float64)))
        return evaluate_native(self._problem, np.asarray(native), episode_seed(config.seed, cid))

    def _take_ahead(self, key: tuple[int, tuple[float, ...]]) -> float | None:
        """The return of the episode ahead of ``key`` (waiting while it runs), else None.
        Episodes ahead of this id that have not started are dropped: this one runs now,
        here, and the other branches' θ for the id will not be asked."""
        with self._ahead_cond:
            self._ahead_cond.wait_for(lambda: self._ahead_running != key)
            stale = [item for item in self._ahead_todo if item[2] == key[0]]
            for item in stale:
                self._ahead_todo.remove(item)
            return self._ahead.pop(key, None)

    def queued(self) -> None:
        """Evaluate the queued candidates now, in the executor's thread."""
        config = self.config
        assert config is not None
        while self._queue:
            cand = self._current = self._queue.popleft()
            ahead = self._take_ahead((cand.candidate_id, cand.theta))
            if ahead is not None:
                self._current = None
                self.counters["episodes_ahead_used"] += 1
                self._succeed(cand, ahead)
                continue
            self.publish_status()  # heartbeat: the episode may take longer than a status period
            try:
                value = self._evaluate(config, cand.candidate_id, cand.theta)
                if not math.isfinite(value):
                    raise ValueError(f"episode return is not finite ({value})")
            except Exception as exc:  # any simulator error becomes a failed episode result
                self._current = None
                self._fail(cand, f"{type(exc).__name__}: {exc}")
                continue
            self._current = None
            self._succeed(cand, value)

    def _on_speculative(self, msg: object) -> None:
        config = self.config
        if config is None:
            return  # nothing is worth doing ahead before the run is known
        cand = self.candidate_for(msg, self.worker_id)
        if cand is None:
            return
        key = (cand.candidate_id, cand.theta)
        with self._ahead_cond:
            known = key in self._ahead or key == self._ahead_running
            known = known or any((c, t) == key for _, _, c, t in self._ahead_todo)
        if cand.candidate_id in self._thetas or known:
            return
        if self._ahead_runs[cand.candidate_id] >= AHEAD_PER_ID:
            self.drop("ahead_limit", f"candidate {cand.candidate_id}: {AHEAD_PER_ID} run ahead")
            return
        with self._ahead_cond:
            full = len(self._ahead_todo) >= AHEAD_KEPT
            if not full:
                self._ahead_todo.append((self._ahead_generation, config, *key))
                self._ahead_cond.notify_all()
        if full:
            self.drop("ahead_queue_full", f"{AHEAD_KEPT} episodes ahead are waiting")
            return
        self._ahead_runs[cand.candidate_id] += 1

    def _run_ahead(self) -> None:
        """The worker thread: run the episodes ahead one after another."""
        while True:
            with self._ahead_cond:
                self._ahead_cond.wait_for(lambda: self._ahead_stop or bool(self._ahead_todo))
                if self._ahead_stop:
                    return
                generation, config, cid, theta = self._ahead_todo.popleft()
                self._ahead_running = (cid, theta)
            try:
                if self._evaluator is None:
                    value = self._episodes.evaluate(config, cid, theta)
                else:
                    value = self._evaluate(config, cid, theta)
            except Exception:  # the real candidate, if asked, runs it again, reporting the error
                value = math.nan
            with self._ahead_cond:
                self._ahead_running = None
                self._ahead_cond.notify_all()
                if generation != self._ahead_generation:
                    continue  # the run changed while the episode ran
                if not math.isfinite(value):
                    self.counters["episodes_ahead_failed"] += 1
                    continue
                self._ahead[(cid, theta)] = value
                while len(self._ahead) > AHEAD_KEPT:
                    self._ahead.popitem(last=False)
                self.counters["episodes_ahead"] += 1


def main(argv: list[str] | None = None) -> NoReturn:
    """``ros2 run localpbo_ros sim_node [--ros-args -p run_id:=...]``."""
    from localpbo_ros.entry import run_node

    run_node(SimNode, argv, stop_when_finished=False)


if __name__ == "__main__":
    main()
