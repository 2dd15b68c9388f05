"""Shared node plumbing: drop counters, throttled warnings, the status topic, suite
publishers/subscriptions, and the parameter services.

Time: a node's timers (status heartbeat, the optimizer's and bridge's ticks) run on the steady
clock, so ``use_sim_time`` (rclpy's own parameter, the only writable one; at start or set while
running) is honoured without stopping them: with it the node's ROS clock, and so the status
stamps, follow ``/clock``, while heartbeats, timeouts and re-publishing keep real time whether
or not a ``/clock`` publisher exists.
"""

from __future__ import annotations

import time
from collections import Counter
from collections.abc import Callable
from typing import Any, TypedDict, Unpack

from rclpy.callback_groups import CallbackGroup
from rclpy.clock import Clock, ClockType
from rclpy.context import Context
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.timer import Timer

from localpbo_msgs_py import DecodeError, Status
from localpbo_msgs_py.topics import STATUS, TopicSpec
from localpbo_ros.params import Param, declare, refuse_unknown

NO_RUN = "none"
"""Run id reported in status messages before a node knows its run."""

WARN_PERIOD_S = 5.0
"""A node logs at most one warning per key (e.g. per drop reason) in this many seconds."""


class WarningThrottle:
    """At most one log line per key per ``period_s``; counts the lines it held back.

    Args:
        period_s: seconds between two lines of the same key.
        clock: monotonic seconds (tests pass their own).
    """

    def __init__(self, period_s: float, clock: Callable[[], float] = time.monotonic) -> None:
        self.period_s = period_s
        self.clock = clock
        self._last: dict[str, float] = {}
        self._held: Counter[str] = Counter()

    def admit(self, key: str) -> int | None:
        """``None`` when a line for ``key`` is held back; else how many were held back since
        the previous line of ``key`` (the caller logs now and says so)."""
        now = self.clock()
        last = self._last.get(key)
        if last is not None and now - last < self.period_s:
            self._held[key] += 1
            return None
        self._last[key] = now
        return self._held.pop(key, 0)

    def held(self) -> dict[str, int]:
        """Lines held back and not yet reported, by key."""
        return dict(self._held)


class NodeOptions(TypedDict, total=False):
    """How a node of the suite starts: ``context``, ``overrides`` and ``cli_args`` of
    :class:`SuiteNode` (see its Args)."""

    context: Context | None
    overrides: dict[str, Any] | None
    cli_args: list[str] | None


def node_arguments(options: NodeOptions) -> dict[str, Any]:
    """rclpy ``Node`` keyword arguments of ``options``: its context, its command-line arguments
    and its overrides as parameter overrides."""
    overrides = options.get("overrides") or {}
    return {
        "context": options.get("context"),
        "cli_args": options.get("cli_args"),
        "parameter_overrides": [Parameter(k, value=v) for k, v in overrides.items()],
    }


class SuiteNode(Node):
    """A node of the suite: declared parameters, counters and a status publisher.

    The node serves the standard parameter services (``ros2 param list/get/describe/set``);
    every declared parameter is read-only, so a ``set`` is refused. A value given for a
    parameter the node does not have is refused at start (:func:`~localpbo_ros.params.
    refuse_unknown`). Timers run on the steady clock (see the module docstring).

    Args:
        name: node name (the executable's name; ``--ros-args -r __node:=other`` renames it).
        params: declared parameters (see :mod:`localpbo_ros.params`).
        context: the rclpy context (a private one in tests and ``localpbo run``).
        overrides: parameter values, as ``--ros-args -p`` would give them.
        cli_args: ROS command-line arguments (remapping, parameters).
        status_period_s: seconds between two status messages.
        warn_period_s: seconds between two warnings of the same kind (see
            :class:`WarningThrottle`); counters stay exact.
    """

    def __init__(
        self,
        name: str,
        params: list[Param],
        *,
        status_period_s: float = 1.0,
        warn_period_s: float = WARN_PERIOD_S,
        **options: Unpack[NodeOptions],
    ) -> None:
        super().__init__(
            name,
            **node_arguments(options),
            start_parameter_services=True,
        )
        self.settings = declare(self, params)
        given = getattr(self, "_parameter_overrides", {})  # rclpy keeps no public accessor
        known = self.list_parameters([], 0).names
        refuse_unknown(self.get_name(), given, known)
        self.counters: Counter[str] = Counter()
        self.warnings = WarningThrottle(warn_period_s)
        self.state = "starting"
        self.status_run_id = NO_RUN
        self._status_pub = self.create_publisher(STATUS.msg_type, STATUS.name, STATUS.qos)
        self.create_timer(status_period_s, self.publish_status)

    def create_timer(
        self,
        timer_period_sec: float,
        callback: Callable[..., Any],
        callback_group: CallbackGroup | None = None,
        clock: Clock | None = None,
        autostart: bool = True,
    ) -> Timer:
        """rclpy's ``create_timer`` on the steady clock unless ``clock`` is given."""
        steady = Clock(clock_type=ClockType.STEADY_TIME) if clock is None else clock
        return super().create_timer(
            timer_period_sec, callback, callback_group, steady, autostart=autostart
        )

    def publisher(self, spec: TopicSpec) -> Any:
        """A publisher on a suite topic with its QoS."""
        return self.create_publisher(spec.msg_type, spec.name, spec.qos)

    def subscribe(self, spec: TopicSpec, callback: Callable[[Any], None]) -> Any:
        """A subscription on a suite topic with its QoS."""
        return self.create_subscription(spec.msg_type, spec.name, callback, spec.qos)

    def warn(self, key: str, text: str) -> None:
        """Log ``text`` as a warning unless a warning of ``key`` was logged within
        ``warn_period_s``; the next line that is logged says how many were held back."""
        held = self.warnings.admit(key)
        if held is None:
            return
        if held:
            text += f" ({held} similar warnings suppressed since the last one)"
        self.get_logger().warning(text)

    def drop(self, reason: str, detail: str) -> None:
        """Drop a bad message: count it (``dropped_<reason>``) and warn (throttled)."""
        self.counters[f"dropped_{reason}"] += 1
        self.warn(f"dropped_{reason}", f"dropped message ({reason}): {detail}")

    def drop_decode(self, error: DecodeError) -> None:
        """Drop a message its decoder refused, counted by the decoder's reason."""
        self.drop(error.reason.value, str(error))

    def status_info(self) -> dict[str, str]:
        """Info items of the status message (``info.<name>``); none by default."""
        return {}

    def counter_snapshot(self) -> dict[str, int]:
        """The counters of the status message (a copy)."""
        return dict(self.counters)

    def publish_status(self, level: int = 0, message: str = "") -> None:
        """Publish state, counters and :meth:`status_info` on ``/localpbo/status``."""
        status = Status(
            self.status_run_id,
            self.get_name(),
            self.state,
            level,
            message[:4000],
            self.counter_snapshot(),
            self.status_info(),
            self.get_clock().now().nanoseconds,
        )
        self._status_pub.publish(status.encode())
