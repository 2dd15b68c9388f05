"""Shared node plumbing: drop counters, the status topic, suite publishers/subscriptions."""

from __future__ import annotations

from collections import Counter
from collections.abc import Callable
from typing import Any

from rclpy.context import Context
from rclpy.node import Node
from rclpy.parameter import Parameter

from localpbo_msgs_py import Status
from localpbo_msgs_py.topics import STATUS, TopicSpec
from localpbo_ros.params import Param, declare

NO_RUN = "none"
"""Run id reported in status messages before a node knows its run."""


class SuiteNode(Node):
    """A node of the suite: declared parameters, counters and a status publisher.

    Args:
        name: node name.
        params: declared parameters (see :mod:`localpbo_ros.params`).
        context: the rclpy context (a private one in tests and ``localpbo run``).
        overrides: parameter values, as ``--ros-args -p`` would give them.
        cli_args: ROS command-line arguments (remapping, parameters).
    """

    def __init__(
        self,
        name: str,
        params: list[Param],
        *,
        context: Context | None = None,
        overrides: dict[str, Any] | None = None,
        cli_args: list[str] | None = None,
        status_period_s: float = 1.0,
    ) -> None:
        super().__init__(
            name,
            context=context,
            cli_args=cli_args,
            parameter_overrides=[Parameter(k, value=v) for k, v in (overrides or {}).items()],
            start_parameter_services=False,
        )
        self.settings = declare(self, params)
        self.counters: Counter[str] = Counter()
        self.state = "starting"
        self.status_run_id = NO_RUN
        self._status_pub = self.create_publisher(STATUS.msg_type, STATUS.name, STATUS.qos)
        self.create_timer(status_period_s, self.publish_status)

    def publisher(self, spec: TopicSpec) -> Any:
        """A publisher on a suite topic with its QoS."""
        return self.create_publisher(spec.msg_type, spec.name, spec.qos)

    def subscribe(self, spec: TopicSpec, callback: Callable[[Any], None]) -> Any:
        """A subscription on a suite topic with its QoS."""
        return self.create_subscription(spec.msg_type, spec.name, callback, spec.qos)

    def drop(self, reason: str, detail: str) -> None:
        """Drop a bad message: count it (``dropped_<reason>``) and warn."""
        self.counters[f"dropped_{reason}"] += 1
        self.get_logger().warning(f"dropped message ({reason}): {detail}")

    def publish_status(self, level: int = 0, message: str = "") -> None:
        """Publish state and counters on ``/localpbo/status``."""
        status = Status(
            self.status_run_id,
            self.get_name(),
            self.state,
            level,
            message[:4000],
            dict(self.counters),
            {},
            self.get_clock().now().nanoseconds,
        )
        self._status_pub.publish(status.encode())
