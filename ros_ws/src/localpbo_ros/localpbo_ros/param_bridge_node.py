"""``param_bridge_node``: evaluates each candidate on a running node through its parameters.

Serves space runs (``localpbo run --space``, optimizer parameter ``space``). At the start of a
run it asks the target node (``target_node``) through the standard parameter services whether
every target parameter (space name, or ``mapping``) exists, is a double, is writable and
accepts the space's bounds (its ``floating_point_range``), and remembers the original values;
otherwise it refuses the run naming the parameter (state ``failed``; the executable exits 1;
``localpbo run`` checks before it starts and exits 2 with no bag) and answers every candidate
with a ``failed`` episode result. A target without parameter services after ``target_wait_s``
is refused the same way.

One trial per candidate, in arrival order: set all parameters at once
(``SetParametersAtomically``), call ``reset_service`` (``std_srvs/srv/Trigger``) if given, then
take the ``std_msgs/msg/Float64`` samples of ``score_topic`` that the target published within
the trial's window (:class:`localpbo_ros.bridge.TrialWindow`: by the middleware's publication
stamps, from the target's answer to the reset, or to the set without a reset service, until
``trial_samples`` samples, the done message's own publication stamp, or ``trial_duration_s``).
Then the trial is checked: the target must answer a ``GetParameters`` call with the
candidate's values (it is alive and was not replaced), the samples must be consecutive from
one publisher, none may be missing for more than ``max_sample_gap_s`` and at least
``min_samples`` must have arrived. The answer to that call also closes the window: it was
published after every sample of the trial, and the target's messages reach this node in the
order they were sent, so the samples still queued are taken before the score is computed.
The samples reduced by ``score_reduce`` (``mean``, ``sum``, ``last``, ``min``, ``max``;
negated for ``score_kind=cost``) are the episode return published on
``/localpbo/episode_result``. Any failed check, a refused set or reset, or a service call that
times out (``service_timeout_s``) gives a ``failed`` episode result naming the reason (the
optimizer's failure policy decides): a score is the trial's own or there is none.
A ``done_service`` call (this node serves it) ends the window when it is handled (a service
request carries no publication stamp here): exact when the target publishes no sample between
its call and the next reset. Results are matched by candidate id; a repeated candidate gets
its stored result.

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
from typing import Any, NoReturn, Unpack

from rcl_interfaces.msg import Parameter as ParameterMsg
from rcl_interfaces.msg import ParameterType
from rcl_interfaces.srv import (
    DescribeParameters,
    GetParameters,
    ListParameters,
    SetParametersAtomically,
)
from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
from rclpy.parameter import Parameter
from rclpy.qos import QoSProfile, ReliabilityPolicy, qos_profile_services_default
from rclpy.type_support import check_is_valid_srv_type
from std_msgs.msg import Bool, Empty, Float64
from std_srvs.srv import Trigger

from localpbo_core.space import ParameterSpace
from localpbo_core.validation import SettingError
from localpbo_msgs_py import CandidateMsg, DecodeError, EpisodeResult, RunConfig, Status
from localpbo_msgs_py.topics import STATUS
from localpbo_ros.base import NodeOptions
from localpbo_ros.bridge import (
    REDUCERS,
    SCORE_KINDS,
    Sample,
    TargetParameter,
    TrialWindow,
    check_listed,
    check_target,
    target_names,
)
from localpbo_ros.driver import space_of
from localpbo_ros.evaluator import EvaluatorNode
from localpbo_ros.params import Param, ParameterError

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
        "Longest trial in seconds after the target's answer to the reset (or set); it ends "
        "earlier on trial_samples samples or a done message.",
        float_range=(0.001, 86_400.0),
    ),
    Param(
        "trial_samples",
        0,
        "End the trial after this many score samples (0: no count); fewer by "
        "trial_duration_s fail the trial.",
        int_range=(0, 10_000_000),
    ),
    Param(
        "min_samples",
        1,
        "A trial with fewer score samples fails.",
        int_range=(1, 10_000_000),
    ),
    Param(
        "max_sample_gap_s",
        1.0,
        "A trial fails when no score sample arrives for this long (the target stalled or "
        "died); 0 turns the check off.",
        float_range=(0.0, 86_400.0),
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
        5.0,
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


class StampedClient:
    """A service client that keeps the header of each response: its publication stamp.

    rclpy's ``Client`` hands a response to its future without the header; this one is polled
    (:meth:`poll`) from the node's timer and returns ``(source_timestamp_ns, response)``,
    the stamp written by the server's process when it sent the answer.
    """

    def __init__(self, node: Any, srv_type: Any, name: str) -> None:
        self.srv_type = srv_type
        self.name = name
        check_is_valid_srv_type(srv_type)  # loads the type support
        with node.handle:
            self._impl = _rclpy.Client(
                node.handle, srv_type, name, qos_profile_services_default.get_c_qos_profile()
            )
        self._pending: int | None = None

    def ready(self) -> bool:
        """True when a server is matched."""
        return bool(self._impl.service_server_is_available())

    def send(self, request: Any) -> None:
        """Send ``request`` (a later response to an earlier request is ignored)."""
        self._pending = int(self._impl.send_request(request))

    def poll(self) -> tuple[int, Any] | None:
        """The response to the last request, once it is here."""
        while self._pending is not None:
            header, response = self._impl.take_response(self.srv_type.Response)
            if header is None:
                return None
            if header.request_id.sequence_number == self._pending:
                self._pending = None
                return int(header.source_timestamp), response
        return None

    def cancel(self) -> None:
        """Forget the pending request."""
        self._pending = None

    def destroy(self) -> None:
        """Release the client."""
        self._impl.destroy_when_not_in_use()


class ParamBridgeNode(EvaluatorNode):
    """The parameter bridge (see module docstring)."""

    def __init__(self, **options: Unpack[NodeOptions]) -> None:
        super().__init__("param_bridge_node", PARAMS, **options)
        s = self.settings
        if not s["target_node"].strip("/"):
            raise ParameterError("target_node", "is required, e.g. /pid_controller_node")
        if s["trial_samples"] and s["min_samples"] > s["trial_samples"]:
            raise ParameterError("min_samples", "must not exceed trial_samples")
        self.target = "/" + s["target_node"].strip("/")
        self.window = TrialWindow(
            s["score_kind"],
            s["score_reduce"],
            samples=s["trial_samples"],
            min_samples=s["min_samples"],
            max_gap_ns=int(s["max_sample_gap_s"] * 1e9),
        )
        self.finished = False
        self.error = ""
        self.refusal: SettingError | None = None
        self.phase = "idle"
        self.space: ParameterSpace | None = None
        self.targets: tuple[str, ...] = ()
        self.originals: dict[str, Any] = {}
        self.applied = False
        self._futures: list[Any] = []
        self._deadline = 0.0
        self._trial_end_ns = 0
        self._done_ns = 0
        self._set = self._client(SetParametersAtomically, "set_parameters_atomically")
        self._list = self._client(ListParameters, "list_parameters")
        self._describe = self._client(DescribeParameters, "describe_parameters")
        self._get = self._client(GetParameters, "get_parameters")
        self._apply = StampedClient(
            self, SetParametersAtomically, self._srv("set_parameters_atomically")
        )
        self._probe = StampedClient(self, GetParameters, self._srv("get_parameters"))
        self._reset: StampedClient | None = None
        self._waiting: StampedClient | None = None
        try:
            if s["reset_service"]:
                self._reset = StampedClient(self, Trigger, s["reset_service"])
            # callbacks of two arguments get the message info (rclpy; not in its stubs)
            self._score = self.create_subscription(
                Float64,
                s["score_topic"],
                self._on_score,  # type: ignore[arg-type]
                SCORE_QOS,
            )
            if s["done_topic"]:
                kind = Bool if s["done_type"] == "bool" else Empty
                self.create_subscription(
                    kind,
                    s["done_topic"],
                    self._on_done_msg,  # type: ignore[arg-type]
                    10,
                )
            if s["done_service"]:
                self.create_service(Trigger, s["done_service"], self._on_done_call)
        except Exception as exc:  # rclpy refuses an invalid topic or service name
            raise ParameterError("score_topic", f"{type(exc).__name__}: {exc}") from None
        self.subscribe(STATUS, self._on_status)
        self.create_timer(TICK_S, self._tick)

    def _srv(self, service: str) -> str:
        return f"{self.target}/{service}"

    def _client(self, srv: Any, service: str) -> Any:
        return self.create_client(srv, self._srv(service))

    def destroy_node(self) -> None:
        """Release the stamped clients, then the node."""
        for client in (self._apply, self._probe, self._reset):
            if client is not None:
                client.destroy()
        super().destroy_node()

    # ------------------------------------------------------------------ run life cycle
    def reset(self) -> None:
        """Another run starts: put the target back and forget this run's trials."""
        self._restore()
        self._queue.clear()
        self._current = None
        self._waiting = None
        self._thetas.clear()
        self._results.clear()
        self.window.close()
        self.phase = "idle"

    def adopt(self, config: RunConfig) -> None:
        """Take the run's space and start checking the target (answers come in ``_tick``)."""
        space = space_of(config)
        if space is None:
            raise SettingError("task", f"{config.task} is not a parameter-space run")
        self.begin_check(space)

    def begin_check(self, space: ParameterSpace) -> None:
        """Start checking that the target can take ``space`` (:meth:`check_target_now` waits
        for the verdict; a run's config starts it by itself)."""
        self.targets = target_names(space, self.settings["mapping"])
        self.space = space
        self.phase = "checking"
        self.refusal = None
        self._futures = []
        self._deadline = time.monotonic() + self.settings["target_wait_s"]

    def check_target_now(self, space: ParameterSpace, spin: Any) -> None:
        """Check the target for ``space`` before any run starts, calling ``spin()`` until the
        verdict (at most ``target_wait_s`` plus ``service_timeout_s``).

        Raises:
            ParameterError: the target cannot take the space (field ``target.<parameter>``)
                or has no parameter services (field ``target_node``).
        """
        self.begin_check(space)
        while self.phase == "checking":
            spin()
        if self.refusal is not None:
            raise ParameterError(self.refusal.field, self.refusal.reason)
        self.phase = "idle"  # the run's config checks again (the target may have changed)

    def _refuse(self, error: SettingError) -> None:
        reason = str(error)
        self.refusal = error
        self.phase = "refused"
        self.error = reason
        self.get_logger().error(f"refusing target {self.target}: {reason}")
        if self.config is None:  # a check before the run: the caller decides
            return
        self.state = "failed"
        self.finished = True
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
    def refusal_reason(self) -> str | None:
        """While the target is refused every candidate fails with the reason (the candidate
        intake itself is :class:`~localpbo_ros.evaluator.EvaluatorNode`'s)."""
        return self.error if self.phase == "refused" else None

    # ------------------------------------------------------------------ trial machine
    def _tick(self) -> None:
        now = time.monotonic()
        if self.phase == "checking":
            self._check(now)
        elif self.phase in ("applying", "resetting", "probing"):
            self._poll(now)
        elif self.phase == "trial":
            self._drain()  # what the executor has not taken yet, before judging silence
            if self.window.stalled(time.time_ns()) or self.window.failure:
                self._finish_trial()
            elif not self._score.handle.get_publisher_count():
                topic = self.settings["score_topic"]
                had = "lost its publisher mid-trial" if self.window.count else "has no publisher"
                self._abort(f"score topic {topic!r} {had}")
            elif self.window.complete or time.time_ns() > self._trial_end_ns:
                self._send_probe()
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
                self._futures = [self._list.call_async(ListParameters.Request(depth=0))]
                self._deadline = now + self._timeout
            elif now > self._deadline:
                wait = self.settings["target_wait_s"]
                self._refuse(
                    SettingError(
                        "target_node",
                        f"{self.target} has no parameter services (waited {wait:g} s, "
                        "target_wait_s): is it running, and on this ROS_DOMAIN_ID?",
                    )
                )
            return
        if not all(f.done() for f in self._futures):
            if now > self._deadline:
                self._refuse(
                    SettingError("target_node", f"{self.target} did not describe its parameters")
                )
            return
        if len(self._futures) == 1:  # the listing: describe only parameters that exist
            try:
                check_listed(self.space, self.targets, set(self._futures[0].result().result.names))
            except SettingError as exc:
                self._refuse(exc)
                return
            self._futures = [
                self._describe.call_async(DescribeParameters.Request(names=self.targets)),
                self._get.call_async(GetParameters.Request(names=self.targets)),
            ]
            self._deadline = now + self._timeout
            return
        described, values = (f.result() for f in self._futures)
        self._futures = []
        info = self._describe_target(described.descriptors, values.values)
        try:
            check_target(self.space, self.targets, info)
        except SettingError as exc:
            self._refuse(exc)
            return
        self.originals = dict(zip(self.targets, values.values, strict=True))
        shown = ", ".join(f"{n}={v.double_value!r}" for n, v in self.originals.items())
        self.get_logger().info(f"target {self.target} checked; original values {shown}")
        self.phase = "ready"

    def _describe_target(
        self, descriptors: list[Any], values: list[Any]
    ) -> dict[str, TargetParameter]:
        if len(descriptors) != len(self.targets) or len(values) != len(self.targets):
            return {}  # the target changed between listing and describing: refused as absent
        return {
            n: TargetParameter(
                n,
                True,
                value.type == ParameterType.PARAMETER_DOUBLE,
                bool(desc.read_only),
                tuple((r.from_value, r.to_value) for r in desc.floating_point_range),
            )
            for n, desc, value in zip(self.targets, descriptors, values, strict=True)
        }

    def _send(self, client: StampedClient, request: Any, phase: str) -> None:
        if not client.ready():
            self._abort(f"{client.name} is not available (target {self.target} gone?)")
            return
        client.send(request)
        self._waiting = client
        self.phase = phase
        self._deadline = time.monotonic() + self._timeout

    def _poll(self, now: float) -> None:
        client = self._waiting
        assert client is not None
        got = client.poll()
        if got is None:
            if now > self._deadline:
                client.cancel()
                self._abort(f"timeout: {client.name} did not answer within {self._timeout:g} s")
            return
        self._waiting = None
        stamp_ns, response = got
        if self.phase == "applying":
            if not response.result.successful:
                self._abort(f"target refused the parameters: {response.result.reason}")
            elif self._reset is not None:
                self._send(self._reset, Trigger.Request(), "resetting")
            else:
                self._begin_trial(stamp_ns)
        elif self.phase == "resetting":
            if not response.success:
                self._abort(f"reset refused: {response.message}")
            else:
                self._begin_trial(stamp_ns)
        else:
            self._probed(response)

    def _start_trial(self, cand: CandidateMsg) -> None:
        self._current = cand
        params = [
            Parameter(n, Parameter.Type.DOUBLE, float(v)).to_parameter_msg()
            for n, v in zip(self.targets, cand.theta, strict=True)
        ]
        self.applied = True
        self.window.arm()  # samples from here on are kept until the window's start is known
        self._send(self._apply, SetParametersAtomically.Request(parameters=params), "applying")

    def _begin_trial(self, start_ns: int) -> None:
        """The target answered at ``start_ns`` (its publication stamp): the window opens."""
        duration_ns = int(self.settings["trial_duration_s"] * 1e9)
        self.window.start(start_ns, duration_ns)
        self._trial_end_ns = start_ns + duration_ns
        self.phase = "trial"
        if self._done_ns > start_ns:  # the done was taken before the answer that opens the window
            self.window.end_at(self._done_ns)
        self._drain()  # samples already queued: earlier ones are told apart by their stamps

    def _send_probe(self) -> None:
        """Ask the target for its parameters: it must be alive with the candidate's values,
        and its answer comes after every sample it published in the trial."""
        self._send(self._probe, GetParameters.Request(names=list(self.targets)), "probing")

    def _probed(self, response: Any) -> None:
        cand = self._current
        assert cand is not None
        values = [
            v.double_value if v.type == ParameterType.PARAMETER_DOUBLE else None
            for v in response.values
        ]
        if values != [float(v) for v in cand.theta]:
            self._abort(
                f"target {self.target} no longer holds the candidate's parameters after the "
                f"trial ({values} instead of {list(cand.theta)}): it was restarted or changed"
            )
            return
        self._drain()
        self._finish_trial()

    def _finish_trial(self) -> None:
        cand, self._current = self._current, None
        assert cand is not None and self.config is not None
        self.phase = "ready"
        score, reason = self.window.close()
        if score is None:
            self._fail(cand, reason)
            return
        result = EpisodeResult.ok(self.config.run_id, cand.candidate_id, score)
        self._results[cand.candidate_id] = result
        self.counters["episodes"] += 1
        self._pub.publish(result.encode())

    def _abort(self, reason: str) -> None:
        if self._waiting is not None:
            self._waiting.cancel()
            self._waiting = None
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
    def _drain(self) -> None:
        """Take every score sample already delivered to this node, in publication order."""
        handle = self._score.handle
        with handle:
            while True:
                taken = handle.take_message(Float64, False)
                if taken is None:
                    return
                self._on_score(*taken)

    def _on_score(self, msg: Float64, info: Any) -> None:
        got = self.window.add(
            float(msg.data), int(info["source_timestamp"]), info.get("publication_sequence_number")
        )
        if got is Sample.NON_FINITE:
            self.drop("non_finite", f"score sample {msg.data!r}")
        elif got is Sample.BEFORE:
            self.counters["scores_before_trial"] += 1
        elif got not in (Sample.TAKEN, Sample.PENDING):
            self.counters["scores_outside_trial"] += 1

    def _trial_done(self, source: str, stamp_ns: int) -> bool:
        self._done_ns = max(self._done_ns, stamp_ns)
        if self.phase == "resetting" or (self.phase == "applying" and self._reset is None):
            return True  # may belong to the trial about to open: applied by _begin_trial
        if self.phase != "trial" or not self.window.end_at(stamp_ns):
            self.drop("outside_trial", f"{source} while no trial runs")
            return False
        return True

    def _on_done_msg(self, msg: Empty | Bool, info: Any) -> None:
        if isinstance(msg, Bool) and not msg.data:
            return
        self._trial_done(self.settings["done_topic"], int(info["source_timestamp"]))

    def _on_done_call(self, request: Trigger.Request, response: Trigger.Response) -> Any:
        response.success = self._trial_done(self.settings["done_service"], time.time_ns())
        response.message = "trial done" if response.success else "no trial runs"
        return response


def main(argv: list[str] | None = None) -> NoReturn:
    """``ros2 run localpbo_ros param_bridge_node --ros-args -p target_node:=/my_controller``."""
    from localpbo_ros.entry import run_node

    run_node(ParamBridgeNode, argv, stop_when_finished=True)


if __name__ == "__main__":
    main()
