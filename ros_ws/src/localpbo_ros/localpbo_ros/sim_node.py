"""``sim_node``: runs one episode per candidate and publishes its return.

Subscribes ``/localpbo/run_config`` and ``/localpbo/candidate``; publishes
``/localpbo/episode_result`` and ``/localpbo/status``. θ arrives in task units and is evaluated
as received (``evaluate_native``) with the candidate's episode seed
(``localpbo_core.seeds.episode_seed(run seed, candidate id)``): exactly what the in-process
run evaluates, whichever process evaluates it and in whichever order.

Idempotent by id: a candidate seen again with the same θ gets its stored result re-published
(no second episode); a failed episode is re-run when its candidate is published again (retry).
An evaluator that raises, or returns a non-finite value, yields a ``failed`` episode result.

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
from collections.abc import Callable
from typing import Any, NoReturn

import numpy as np
from rclpy.context import Context

from localpbo_core.seeds import episode_seed
from localpbo_core.session import evaluate_native
from localpbo_msgs_py import EpisodeResult, RunConfig
from localpbo_msgs_py.topics import CANDIDATE, EPISODE_RESULT
from localpbo_ros.driver import problem_of
from localpbo_ros.follower import FollowerNode
from localpbo_ros.pool import BUSY_INFO, WORKER_INFO, new_worker_id

Evaluator = Callable[[RunConfig, int, np.ndarray], float]
"""``(run config, candidate id, θ in task units as received) -> episode return``."""


class SimNode(FollowerNode):
    """The simulator node (see module docstring).

    Args:
        evaluator: replaces the task's own episode (tests, your own simulator).
    """

    def __init__(
        self,
        *,
        context: Context | None = None,
        overrides: dict[str, Any] | None = None,
        cli_args: list[str] | None = None,
        evaluator: Evaluator | None = None,
    ) -> None:
        super().__init__("sim_node", [], context=context, overrides=overrides, cli_args=cli_args)
        self._evaluator = evaluator
        self._problem: Any = None
        self._thetas: dict[int, tuple[float, ...]] = {}
        self._results: dict[int, EpisodeResult] = {}
        self.worker_id = new_worker_id(self.get_name())
        self.busy: int | None = None
        self._pub = self.publisher(EPISODE_RESULT)
        self.subscribe(CANDIDATE, self._on_candidate)
        self.publish_status()  # announce the worker now, not a status period later

    def status_info(self) -> dict[str, str]:
        """The worker id and the candidate being evaluated (empty when idle)."""
        return {WORKER_INFO: self.worker_id, BUSY_INFO: "" if self.busy is None else str(self.busy)}

    def close(self) -> None:
        """Stopping (SIGINT/SIGTERM): say so, so the optimizer hands this worker's candidate
        to another worker at once instead of after ``worker_timeout_s``."""
        self.state = "stopped"
        self.publish_status()

    def reset(self) -> None:
        """Forget the previous run's candidates and results."""
        self._thetas.clear()
        self._results.clear()

    def adopt(self, config: RunConfig) -> None:
        """Build the task of the run (unless an evaluator was given)."""
        if self._evaluator is None:
            self._problem = problem_of(config)
            if self._problem.dim != config.dim:
                raise ValueError(f"dim: task has {self._problem.dim}, config {config.dim}")

    def _evaluate(self, config: RunConfig, cid: int, native: tuple[float, ...]) -> float:
        if self._evaluator is not None:
            return float(self._evaluator(config, cid, np.asarray(native, dtype=np.float64)))
        return evaluate_native(self._problem, np.asarray(native), episode_seed(config.seed, cid))

    def _on_candidate(self, msg: object) -> None:
        if self.hold(self._on_candidate, msg):
            return
        config = self.config
        assert config is not None
        cand = self.candidate_for(msg, self.worker_id)
        if cand is None:
            return
        known = self._thetas.get(cand.candidate_id)
        if known is not None and known != cand.theta:
            self.drop("conflicting_candidate", f"candidate {cand.candidate_id} changed θ")
            return
        self._thetas[cand.candidate_id] = cand.theta
        cached = self._results.get(cand.candidate_id)
        if cached is not None:
            self.counters["results_repeated"] += 1
            self._pub.publish(cached.encode())
            return
        self.busy = cand.candidate_id
        self.publish_status()  # heartbeat: the episode may take longer than a status period
        try:
            value = self._evaluate(config, cand.candidate_id, cand.theta)
            if not math.isfinite(value):
                raise ValueError(f"episode return is not finite ({value})")
            result = EpisodeResult.ok(config.run_id, cand.candidate_id, value)
            self._results[cand.candidate_id] = result
            self.counters["episodes"] += 1
        except Exception as exc:  # any simulator error becomes a failed episode result
            self.counters["episodes_failed"] += 1
            self.warn("episode_failed", f"episode of candidate {cand.candidate_id} failed: {exc}")
            text = f"{type(exc).__name__}: {exc}"[:4000] or "error"
            result = EpisodeResult.failed(config.run_id, cand.candidate_id, text)
        self.busy = None
        self._pub.publish(result.encode())


def main(argv: list[str] | None = None) -> NoReturn:
    """``ros2 run localpbo_ros sim_node [--ros-args -p run_id:=...]``."""
    from localpbo_ros.entry import run_node

    run_node(SimNode, argv, stop_when_finished=False)


if __name__ == "__main__":
    main()
