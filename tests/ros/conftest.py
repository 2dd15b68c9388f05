"""Headless rclpy fixtures: a private Context per test, a SingleThreadedExecutor driven from the
test thread, discovery range OFF so nothing leaves the process, and the host-only Fast DDS
profile so its sockets are bound to 127.0.0.1."""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

import pytest
import rclpy
from localpbo_ros.dds import PROFILE_FILE
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node

from localpbo_msgs_py.topics import TopicSpec

SMALL_TASK = {"episode_steps": 50, "value_range": 50.0}
"""Swimmer cut to 50 steps (a few ms per episode); value_range set for the oracle noise."""


class Harness:
    """Nodes on one private context; a probe node publishes and collects suite messages."""

    def __init__(self, ctx: Context) -> None:
        self.ctx = ctx
        self.executor = SingleThreadedExecutor(context=ctx)
        self.nodes: list[Node] = []
        self.probe = self.add(Node("probe", context=ctx, start_parameter_services=False))
        self._pubs: dict[str, Any] = {}

    def add(self, node: Node) -> Any:
        self.nodes.append(node)
        self.executor.add_node(node)
        return node

    def remove(self, node: Node) -> None:
        self.executor.remove_node(node)
        self.nodes.remove(node)
        node.destroy_node()

    def collect(self, spec: TopicSpec) -> list[Any]:
        got: list[Any] = []
        self.probe.create_subscription(spec.msg_type, spec.name, got.append, spec.qos)
        return got

    def publisher(self, spec: TopicSpec) -> Any:
        """The probe's publisher on ``spec`` (created once; waits for a subscriber)."""
        if spec.name not in self._pubs:
            pub = self.probe.create_publisher(spec.msg_type, spec.name, spec.qos)
            self._pubs[spec.name] = pub
            self.spin_until(lambda: pub.get_subscription_count() > 0, 5.0)
        return self._pubs[spec.name]

    def publish(self, spec: TopicSpec, msg: object) -> None:
        self.publisher(spec).publish(msg)

    def publish_msg(self, topic: str, msg: Any) -> None:
        """Publish on any topic (reliable, depth 100; waits once for a subscriber)."""
        if topic not in self._pubs:
            pub = self.probe.create_publisher(type(msg), topic, 100)
            self._pubs[topic] = pub
            self.spin_until(lambda: pub.get_subscription_count() > 0, 5.0)
        self._pubs[topic].publish(msg)

    def spin_until(self, pred: Callable[[], bool], timeout: float) -> bool:
        end = time.monotonic() + timeout
        while not pred():
            if time.monotonic() > end:
                return False
            self.executor.spin_once(timeout_sec=0.01)
        return True

    def spin_for(self, seconds: float) -> None:
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            self.executor.spin_once(timeout_sec=0.01)

    def close(self) -> None:
        for node in list(self.nodes):
            self.remove(node)
        self.executor.shutdown()
        rclpy.shutdown(context=self.ctx)


@pytest.fixture
def ros(monkeypatch: pytest.MonkeyPatch) -> Any:
    # what a one-process localpbo run uses: the host-only profile (sockets on 127.0.0.1) with
    # discovery OFF; Fast DDS reads the profile at the process's first participant
    monkeypatch.setenv("FASTRTPS_DEFAULT_PROFILES_FILE", str(PROFILE_FILE))
    monkeypatch.setenv("ROS_AUTOMATIC_DISCOVERY_RANGE", "OFF")
    ctx = Context()
    rclpy.init(context=ctx)
    harness = Harness(ctx)
    yield harness
    harness.close()
