"""``param_bridge_node``: evaluates each candidate on a running node through its parameters.

Serves space runs (``localpbo run --space``, optimizer parameter ``space``). At the start of a
run it asks the target node (``target_node``) through the standard parameter services whether
every target parameter (space name, or ``mapping``) exists, is a double, is writable and
accepts the space's bounds (its ``floating_point_range``), and remembers the original values;
otherwise it refuses the run (state ``failed``, the reason names the parameter; the executable
exits 1) and answers every candidate with a ``failed`` episode result.

One trial per candidate, in arrival order: set all parameters at once
(``SetParametersAtomically``), call ``reset_service`` (``std_srvs/srv/Trigger``) if given, then
collect ``std_msgs/msg/Float64`` samples from ``score_topic`` until ``trial_duration_s`` has
passed, ``trial_samples`` samples arrived, or the trial is declared done (``done_topic``:
``std_msgs/Empty`` or a true ``std_msgs/Bool``; or a call of the ``done_service`` this node
serves). A done message may overtake the last samples (topics are not ordered among each
other); when the number of samples is known, ``trial_samples`` makes the window exact. The
samples reduced by ``score_reduce`` (``mean``, ``sum``, ``last``, ``min``, ``max``; negated for
``score_kind=cost``) are the episode return published on ``/localpbo/episode_result``. A
target that is gone, a refused set, a service call that times out (``service_timeout_s``) or a
trial without samples gives a ``failed`` episode result (the optimizer's failure policy
decides). Results are matched by candidate id; a repeated candidate gets its stored result.

The original parameters are set back when the run ends (the optimizer's status says ``done``
or ``failed``), when another run starts, and when the node stops (SIGINT, SIGTERM, ``close``).
Non-finite score samples and done signals outside a trial are dropped and counted.

Pool worker (:mod:`localpbo_ros.pool`): like ``sim_node``, the bridge announces its worker id
and current trial in its status heartbeats (``info.worker``, ``info.busy``) and takes only the
candidates assigned to it or unassigned ones (others: ``candidates_for_others``), so several
bridges, each on its own controller instance, share a run.
"""

from __future__ import annotations

import time
from collections import deque
from typing import Any, NoReturn

from rcl_interfaces.msg import Parameter as ParameterMsg
from rcl_interfaces.msg import ParameterType
from rcl_interfaces.srv import (
    DescribeParameters,
    GetParameters,
    ListParameters,
    SetParametersAtomically,
)
from rclpy.context import Context
from rclpy.parameter import Parameter
from rclpy.qos import QoSProfile, ReliabilityPolicy
from std_msgs.msg import Bool, Empty, Float64
from std_srvs.srv import Trigger

from localpbo_core.space import ParameterSpace
from localpbo_core.validation import SettingError
from localpbo_msgs_py import CandidateMsg, DecodeError, EpisodeResult, RunConfig, Status
from localpbo_msgs_py.topics import CANDIDATE, EPISODE_RESULT, STATUS
from localpbo_ros.bridge import (
    REDUCERS,
    SCORE_KINDS,
    ScoreWindow,
    TargetParameter,
    check_target,
    target_names,
)
from localpbo_ros.driver import space_of
from localpbo_ros.follower import FollowerNode
from localpbo_ros.params import Param, ParameterError
from localpbo_ros.pool import BUSY_INFO, WORKER_INFO, new_worker_id

PARAMS = [
    Param("target_node", "", "Node whose parameters are tuned, e.g. /pid_controller_node."),
    Param(
        "mapping",
        "{}",
        'Space parameter -> target parameter name as a JSON object, e.g. {"kp": "pid.p"}; '
        "unmapped ones keep their name.",
        json_object=True,
    ),
    Param("reset_service", "", "std_srvs/srv/Trigger called before each trial (empty: none)."),
    Param(
        "trial_duration_s",
        1.0,
        "Longest trial in seconds (it ends earlier when declared done).",
        float_range=(0.001, 86_400.0),
    ),
    Param(
        "trial_samples",
        0,
        "End the trial after this many score samples (0: no count); fewer by "
        "trial_duration_s fail the trial. Exact even when samples and done race.",
        int_range=(0, 10_000_000),
    ),
    Param("done_topic", "", "Topic that ends the trial (empty: none)."),
    Param(
        "done_type",
        "empty",
        "Type of done_topic: std_msgs/Empty, or std_msgs/Bool (true ends the trial).",
        choices=("empty", "bool"),
    ),
    Param("done_service", "", "std_srvs/srv/Trigger this node serves to end the trial."),
    Param("score_topic", "score", "std_msgs/msg/Float64 samples of the trial's score."),
    Param("score_kind", "cost", "reward: higher is better; cost: lower.", choices=SCORE_KINDS),
    Param("score_reduce", "mean", "How the trial's samples become one score.", choices=REDUCERS),
    Param(
        "service_timeout_s",
        2.0,
        "Seconds a service call of the target may take.",
        float_range=(0.01, 3600.0),
    ),
    Param(
        "target_wait_s",
        30.0,
        "Seconds to wait for the target's parameter services when a run starts.",
        float_range=(0.0, 86_400.0),
    ),
    Param(
        "optimizer_node",
        "optimizer_node",
        "Node name of the optimizer whose status done/failed ends the run.",
    ),
]

TICK_S = 0.01
SCORE_QOS = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE)
"""Reliable and deep: a controller may publish a whole episode's samples in one burst."""
RUN_OVER = ("done", "failed")


class ParamBridgeNode(FollowerNode):
    """The parameter bridge (see module docstring)."""

    def __init__(
        self,
        *,
        context: Context | None = None,
        overrides: dict[str, Any] | None = None,
        cli_args: list[str] | None = None,
    ) -> None:
        super().__init__(
            "param_bridge_node", PARAMS, context=context, overrides=overrides, cli_args=cli_args
        )
        s = self.settings
        if not s["target_node"].strip("/"):
            raise ParameterError("target_node", "is required, e.g. /pid_controller_node")
        self.target = "/" + s["target_node"].strip("/")
        self.window = ScoreWindow(s["score_kind"], s["score_reduce"])
        self.finished = False
        self.error = ""
        self.phase = "idle"
        self.space: ParameterSpace | None = None
        self.targets: tuple[str, ...] = ()
        self.originals: dict[str, Any] = {}
        self.applied = False
        self._queue: deque[CandidateMsg] = deque()
        self._current: CandidateMsg | None = None
        self._thetas: dict[int, tuple[float, ...]] = {}
        self._results: dict[int, EpisodeResult] = {}
        self._futures: list[Any] = []
        self._deadline = 0.0
        self._trial_end = 0.0
        self._done_flag = False
        self._set = self._client(SetParametersAtomically, "set_parameters_atomically")
        self._list = self._client(ListParameters, "list_parameters")
        self._describe = self._client(DescribeParameters, "describe_parameters")
        self._get = self._client(GetParameters, "get_parameters")
        self._reset = None
        try:
            if s["reset_service"]:
                self._reset = self.create_client(Trigger, s["reset_service"])
            self.create_subscription(Float64, s["score_topic"], self._on_score, SCORE_QOS)
            if s["done_topic"]:
                kind = Bool if s["done_type"] == "bool" else Empty
                self.create_subscription(kind, s["done_topic"], self._on_done_msg, 10)
            if s["done_service"]:
                self.create_service(Trigger, s["done_service"], self._on_done_call)
        except Exception as exc:  # rclpy refuses an invalid topic or service name
            raise ParameterError("score_topic", f"{type(exc).__name__}: {exc}") from None
        self.worker_id = new_worker_id(self.get_name())
        self._pub = self.publisher(EPISODE_RESULT)
        self.subscribe(CANDIDATE, self._on_candidate)
        self.subscribe(STATUS, self._on_status)
        self.create_timer(TICK_S, self._tick)

    def status_info(self) -> dict[str, str]:
        """The worker id and the candidate on trial (empty when idle)."""
        busy = "" if self._current is None else str(self._current.candidate_id)
        return {WORKER_INFO: self.worker_id, BUSY_INFO: busy}

    def _client(self, srv: Any, service: str) -> Any:
        return self.create_client(srv, f"{self.target}/{service}")

    # ------------------------------------------------------------------ run life cycle
    def reset(self) -> None:
        """Another run starts: put the target back and forget this run's trials."""
        self._restore()
        self._queue.clear()
        self._current = None
        self._thetas.clear()
        self._results.clear()
        self.window.close()
        self.phase = "idle"

    def adopt(self, config: RunConfig) -> None:
        """Take the run's space and start checking the target (answers come in ``_tick``)."""
        space = space_of(config)
        if space is None:
            raise SettingError("task", f"{config.task} is not a parameter-space run")
        self.targets = target_names(space, self.settings["mapping"])
        self.space = space
        self.phase = "checking"
        self._futures = []
        self._deadline = time.monotonic() + self.settings["target_wait_s"]

    def _refuse(self, reason: str) -> None:
        self.phase = "refused"
        self.state = "failed"
        self.finished = True
        self.error = reason
        self.get_logger().error(f"refusing target {self.target}: {reason}")
        self.publish_status(2, reason)
        while self._queue:
            self._fail(self._queue.popleft(), reason)

    def _on_status(self, msg: object) -> None:
        status = Status.decode(msg)
        if isinstance(status, DecodeError):
            self.drop_decode(status)
            return
        if (
            status.node == self.settings["optimizer_node"]
            and status.run_id == self.run_id
            and status.state in RUN_OVER
            and self.applied
        ):
            self.get_logger().info(f"run {self.run_id!r} is {status.state}: restoring the target")
            self._queue.clear()
            self._restore()

    # ------------------------------------------------------------------ restore
    def _restore(self) -> Any:
        """Send the original values (once per applied candidate); the call's future."""
        if not self.applied or not self.originals:
            return None
        self.applied = False
        params = [ParameterMsg(name=n, value=v) for n, v in self.originals.items()]
        self.counters["restores"] += 1
        return self._set.call_async(SetParametersAtomically.Request(parameters=params))

    @property
    def close_timeout_s(self) -> float:
        """How long ``close`` may wait for the target to take its parameters back."""
        return float(self.settings["service_timeout_s"])

    def close(self) -> None:
        """Stopping: say so (the optimizer hands this worker's candidate to another one), set
        the original parameters back and wait (``service_timeout_s``)."""
        if self.state != "failed":
            self.state = "stopped"
            self.publish_status()
        future = self._restore()
        if future is None:
            return
        end = time.monotonic() + self.settings["service_timeout_s"]
        executor = self.executor
        try:
            while not future.done() and time.monotonic() < end and executor is not None:
                executor.spin_once(timeout_sec=0.02)
        except Exception as exc:  # the context is already shut down
            self.get_logger().error(f"could not restore {self.target}: {exc}")
            return
        ok = future.done() and future.result().result.successful
        text = "restored" if ok else "could NOT restore"
        self.get_logger().info(f"{text} the original parameters of {self.target}")

    # ------------------------------------------------------------------ candidates
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
        elif self.phase == "refused":
            self._fail(cand, self.error)
        elif cand.candidate_id in {c.candidate_id for c in self._queue} or (
            self._current is not None and self._current.candidate_id == cand.candidate_id
        ):
            self.counters["candidates_repeated"] += 1
        elif len(self._queue) >= self.settings["max_pending"]:
            self.drop("buffer_full", f"more than {self.settings['max_pending']} trials waiting")
        else:
            self._queue.append(cand)

    # ------------------------------------------------------------------ trial machine
    def _tick(self) -> None:
        now = time.monotonic()
        if self.phase == "checking":
            self._check(now)
        elif self.phase in ("applying", "resetting"):
            if self._futures[0].done():
                self._answered(self._futures[0].result())
            elif now > self._deadline:
                self._abort(f"timeout: {self.phase} took more than {self._timeout} s")
        elif self.phase == "trial":
            if not self._set.service_is_ready():
                self._abort(f"target node {self.target} disappeared during the trial")
            elif self._done_flag or now >= self._trial_end:
                self._finish_trial()
        elif self.phase == "ready" and self._queue:
            self._start_trial(self._queue.popleft())

    @property
    def _timeout(self) -> float:
        return float(self.settings["service_timeout_s"])

    def _check(self, now: float) -> None:
        assert self.space is not None
        clients = (self._list, self._describe, self._get)
        if not self._futures:
            if all(c.service_is_ready() for c in clients):
                self._futures = [
                    self._list.call_async(ListParameters.Request(depth=0)),
                    self._describe.call_async(DescribeParameters.Request(names=self.targets)),
                    self._get.call_async(GetParameters.Request(names=self.targets)),
                ]
                self._deadline = now + self._timeout
            elif now > self._deadline:
                wait = self.settings["target_wait_s"]
                self._refuse(f"target node {self.target} has no parameter services ({wait} s)")
            return
        if not all(f.done() for f in self._futures):
            if now > self._deadline:
                self._refuse(f"target node {self.target} did not describe its parameters")
            return
        listed, described, values = (f.result() for f in self._futures)
        self._futures = []
        info = self._describe_target(set(listed.result.names), described.descriptors, values.values)
        try:
            check_target(self.space, self.targets, info)
        except SettingError as exc:
            self._refuse(str(exc))
            return
        self.originals = dict(zip(self.targets, values.values, strict=True))
        shown = ", ".join(f"{n}={v.double_value!r}" for n, v in self.originals.items())
        self.get_logger().info(f"target {self.target} checked; original values {shown}")
        self.phase = "ready"

    def _describe_target(
        self, listed: set[str], descriptors: list[Any], values: list[Any]
    ) -> dict[str, TargetParameter]:
        if len(descriptors) != len(self.targets) or len(values) != len(self.targets):
            return {n: TargetParameter(n, n in listed) for n in self.targets}
        return {
            n: TargetParameter(
                n,
                n in listed,
                value.type == ParameterType.PARAMETER_DOUBLE,
                bool(desc.read_only),
                tuple((r.from_value, r.to_value) for r in desc.floating_point_range),
            )
            for n, desc, value in zip(self.targets, descriptors, values, strict=True)
        }

    def _call(self, client: Any, request: Any, phase: str) -> None:
        self._futures = [client.call_async(request)]
        self.phase = phase
        self._deadline = time.monotonic() + self._timeout

    def _start_trial(self, cand: CandidateMsg) -> None:
        self._current = cand
        if not self._set.service_is_ready():
            self._abort(f"target node {self.target} is not available")
            return
        params = [
            Parameter(n, Parameter.Type.DOUBLE, float(v)).to_parameter_msg()
            for n, v in zip(self.targets, cand.theta, strict=True)
        ]
        self.applied = True
        self._call(self._set, SetParametersAtomically.Request(parameters=params), "applying")

    def _answered(self, response: Any) -> None:
        if self.phase == "applying":
            if response is None or not response.result.successful:
                why = "no response" if response is None else response.result.reason
                self._abort(f"target refused the parameters: {why}")
            elif self._reset is not None:
                if not self._reset.service_is_ready():
                    self._abort(f"reset service {self._reset.srv_name} is not available")
                    return
                self._begin_window()
                self._call(self._reset, Trigger.Request(), "resetting")
            else:
                self._begin_window()
                self._begin_trial()
        elif response is None or not response.success:
            why = "no response" if response is None else response.message
            self._abort(f"reset refused: {why}")
        else:
            self._begin_trial()

    def _begin_window(self) -> None:
        self._done_flag = False
        self.window.start()

    def _begin_trial(self) -> None:
        self._futures = []
        self.phase = "trial"
        self._trial_end = time.monotonic() + self.settings["trial_duration_s"]

    def _finish_trial(self) -> None:
        cand, self._current = self._current, None
        assert cand is not None and self.config is not None
        self.phase = "ready"
        samples = self.window.count
        score = self.window.close()
        wanted = self.settings["trial_samples"]
        if wanted and samples < wanted:
            self._fail(cand, f"only {samples} of {wanted} score samples by the end of the trial")
            return
        if score is None:
            topic = self.settings["score_topic"]
            self._fail(cand, f"no finite score from {samples} samples on {topic!r}")
            return
        result = EpisodeResult.ok(self.config.run_id, cand.candidate_id, score)
        self._results[cand.candidate_id] = result
        self.counters["episodes"] += 1
        self._pub.publish(result.encode())

    def _abort(self, reason: str) -> None:
        for future in self._futures:
            for client in (self._set, self._reset):
                if client is not None:
                    client.remove_pending_request(future)
        self._futures = []
        self.window.close()
        cand, self._current = self._current, None
        self.phase = "ready"
        if cand is not None:
            self._fail(cand, reason)

    def _fail(self, cand: CandidateMsg, reason: str) -> None:
        assert self.config is not None
        self.counters["episodes_failed"] += 1
        self.warn("episode_failed", f"trial of candidate {cand.candidate_id} failed: {reason}")
        result = EpisodeResult.failed(self.config.run_id, cand.candidate_id, reason[:4000])
        self._pub.publish(result.encode())

    # ------------------------------------------------------------------ trial inputs
    def _full(self) -> bool:
        wanted = self.settings["trial_samples"]
        return bool(wanted) and self.window.count >= wanted

    def _on_score(self, msg: Float64) -> None:
        if not self.window.open or self._full():
            self.counters["scores_outside_trial"] += 1
        elif not self.window.add(float(msg.data)):
            self.drop("non_finite", f"score sample {msg.data!r}")
        elif self._full():
            self._done_flag = True

    def _trial_done(self, source: str) -> bool:
        if not self.window.open:
            self.drop("outside_trial", f"{source} while no trial runs")
            return False
        self._done_flag = True
        return True

    def _on_done_msg(self, msg: Empty | Bool) -> None:
        if isinstance(msg, Bool) and not msg.data:
            return
        self._trial_done(self.settings["done_topic"])

    def _on_done_call(self, request: Trigger.Request, response: Trigger.Response) -> Any:
        response.success = self._trial_done(self.settings["done_service"])
        response.message = "trial done" if response.success else "no trial runs"
        return response


def main(argv: list[str] | None = None) -> NoReturn:
    """``ros2 run localpbo_ros param_bridge_node --ros-args -p target_node:=/my_controller``."""
    from localpbo_ros.entry import run_node

    run_node(ParamBridgeNode, argv, stop_when_finished=True)


if __name__ == "__main__":
    main()
