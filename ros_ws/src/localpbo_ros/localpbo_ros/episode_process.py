"""Episodes ahead in a process of their own: off the interpreter lock of the nodes' process.

``localpbo run`` with a person judging runs every node in one process, and while the person
watches a duel that process prepares the next one for each possible answer: the optimizer's
branches (:mod:`localpbo_core.speculation`), the simulator's episodes ahead
(:mod:`localpbo_ros.sim_node`) and the judge's replays ahead (:mod:`localpbo_ros.rollouts`).
Threads share one interpreter lock: on Hopper a long episode takes ~110 ms and its replay
~170 ms, three of each per duel, and the executor that carries the person's answer waits for
the lock behind them. An :class:`EpisodeProcess` runs such episodes in one worker process
(``spawn``: a fresh interpreter, nothing of DDS inherited), so they use another core and the
nodes' process keeps its lock for the answer.

The worker builds the run's task from the run config (:func:`localpbo_ros.driver.problem_of`,
kept for the next call) and calls the very functions the nodes call in-process
(``evaluate_native`` with the candidate's episode seed; the task's ``record_native``), so a
return or a replay from the worker is the one the node would have computed: episodes are
pure functions of run seed, candidate id and θ. The process starts on first use (a run
without a person never starts it), ignores SIGINT (a Ctrl-C is the node's to handle) and
ends within ``PARENT_CHECK_S`` of its parent, however the parent ended. A worker that dies
fails the calls under way (:class:`EpisodeProcessError`) and the next call starts a new one.
"""

from __future__ import annotations

import contextlib
import multiprocessing
import os
import signal
import threading
import time
from concurrent.futures import CancelledError, Future, ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from typing import Any

from localpbo_msgs_py import RunConfig

__all__ = ["EpisodeProcess", "EpisodeProcessError"]

PARENT_CHECK_S = 0.5
"""Seconds between two checks of the worker that the process that started it still runs."""


class EpisodeProcessError(RuntimeError):
    """The worker process could not run the episode (it died, or could not start)."""


_task: tuple[RunConfig, Any] | None = None
"""The worker's task: the run config it was built from and the problem."""


def _init_worker(parent: int, niceness: int) -> None:
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    if niceness > 0:
        os.nice(niceness)

    def watch() -> None:  # the parent gone (even SIGKILLed): end too, episode or not
        while os.getppid() == parent:
            time.sleep(PARENT_CHECK_S)
        os._exit(0)

    threading.Thread(target=watch, name="episode-process-parent", daemon=True).start()


def _problem(config: RunConfig) -> Any:
    global _task
    if _task is None or _task[0] != config:
        from localpbo_ros.driver import problem_of

        _task = (config, problem_of(config))
    return _task[1]


def _evaluate(config: RunConfig, candidate_id: int, native: tuple[float, ...]) -> float:
    import numpy as np

    from localpbo_core.seeds import episode_seed
    from localpbo_core.session import evaluate_native

    return evaluate_native(
        _problem(config), np.asarray(native), episode_seed(config.seed, candidate_id)
    )


def _record(config: RunConfig, candidate_id: int, native: tuple[float, ...], stride: int) -> Any:
    import numpy as np

    from localpbo_core.seeds import episode_seed

    return _problem(config).record_native(
        np.asarray(native, dtype=np.float64), episode_seed(config.seed, candidate_id), stride
    )


class EpisodeProcess:
    """One worker process running episodes of a run's task (see module docstring).

    Calls block the calling thread (not the interpreter) until the worker answers; calls from
    several threads are served one after another.

    Args:
        niceness: added to the worker's nice value, so that on a busy machine its work
            yields the CPU to what a person waits for (the judge's replays, which only
            illustrate a duel, give way to the episodes ahead, which open it).
    """

    def __init__(self, niceness: int = 0) -> None:
        self.niceness = niceness
        self._lock = threading.Lock()
        self._pool: ProcessPoolExecutor | None = None
        self._closed = False

    def evaluate(self, config: RunConfig, candidate_id: int, native: tuple[float, ...]) -> float:
        """The return of candidate ``candidate_id``'s episode with θ ``native`` (task units)
        (what ``sim_node`` computes).

        Raises:
            EpisodeProcessError: the worker died or could not start.
            Exception: what the episode raised (e.g. θ outside the task's box).
        """
        return float(self._call(_evaluate, config, candidate_id, tuple(native)))

    def record(
        self, config: RunConfig, candidate_id: int, native: tuple[float, ...], stride: int
    ) -> Any:
        """The task's ``record_native`` of that episode (what the judge replays).

        Raises:
            EpisodeProcessError: the worker died or could not start.
            Exception: what the episode raised.
        """
        return self._call(_record, config, candidate_id, tuple(native), stride)

    def worker_pid(self) -> int:
        """The worker's process id (starting it if needed).

        Raises:
            EpisodeProcessError: the worker died or could not start.
        """
        return int(self._call(os.getpid))

    def warm(self, config: RunConfig) -> None:
        """Start the worker and build the run's task there now, without waiting (the first
        episode then does not wait for a new interpreter); a no-op once closed."""
        with contextlib.suppress(EpisodeProcessError, BrokenProcessPool):
            self._submit(_problem, config)

    def _submit(self, fn: Any, *args: Any) -> tuple[ProcessPoolExecutor, Future[Any]]:
        """Hand ``fn(*args)`` to the worker (started if needed); under the lock, so that
        :meth:`close` never comes between the check and the submission."""
        with self._lock:
            if self._closed:
                raise EpisodeProcessError("the episode process is closed")
            if self._pool is None:
                self._pool = ProcessPoolExecutor(
                    1,
                    mp_context=multiprocessing.get_context("spawn"),
                    initializer=_init_worker,
                    initargs=(os.getpid(), self.niceness),
                )
            return self._pool, self._pool.submit(fn, *args)

    def _call(self, fn: Any, *args: Any) -> Any:
        pool: ProcessPoolExecutor | None = None
        try:
            pool, future = self._submit(fn, *args)
            return future.result()
        except BrokenProcessPool as exc:
            with self._lock:
                if self._pool is pool:
                    self._pool = None  # the next call starts a new worker
            if pool is not None:
                pool.shutdown(wait=False, cancel_futures=True)
            raise EpisodeProcessError(f"the episode process ended: {exc}") from None
        except CancelledError:  # closed while this call waited
            raise EpisodeProcessError("the episode process was closed") from None

    def close(self) -> None:
        """Stop the worker (after the episode under way, if any); later calls fail."""
        with self._lock:
            self._closed = True
            pool, self._pool = self._pool, None
        if pool is not None:
            pool.shutdown(wait=True, cancel_futures=True)  # an episode under way ends first
