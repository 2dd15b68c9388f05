"""``recorder_node``: records every suite topic, as serialized CDR, into one MCAP bag.

Subscribes raw (no deserialization) to each topic of ``localpbo_msgs_py.topics.ALL_TOPICS``
(state topics transient-local, so the latched run config and incumbent are recorded even when
published before the recorder joined) and appends the bytes with
``BagWriter.write_serialized``; channels carry the publishers' ``offered_qos_profiles``
(DESIGN.md §5). The writer closes a chunk and flushes every ``flush_interval_s``, so a killed
process loses at most that much.
"""

from __future__ import annotations

import sys
from collections.abc import Iterable
from pathlib import Path
from typing import Any

from rclpy.context import Context
from rclpy.event_handler import SubscriptionEventCallbacks
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

from localpbo_msgs_py.bag import BagWriter
from localpbo_msgs_py.topics import ALL_TOPICS, EVENT_QOS, TopicSpec
from localpbo_ros.base import SuiteNode
from localpbo_ros.params import Param, ParameterError

PARAMS = [
    Param("path", "localpbo_run.mcap", "Output .mcap file (overwritten)."),
    Param(
        "flush_interval_s",
        0.05,
        "Close the open chunk and flush at least this often.",
        float_range=(0.001, 60.0),
    ),
]

RECORD_DEPTH = 1000
"""History depth of the recorder's subscriptions (bursts are not lost while it writes)."""


def recording_qos(spec: TopicSpec) -> QoSProfile:
    """Reliable, deep history; transient-local for latched topics."""
    durable = spec.qos.durability == DurabilityPolicy.TRANSIENT_LOCAL
    return QoSProfile(
        history=HistoryPolicy.KEEP_LAST,
        depth=RECORD_DEPTH if not durable else max(spec.qos.depth, 1),
        reliability=ReliabilityPolicy.RELIABLE,
        durability=DurabilityPolicy.TRANSIENT_LOCAL if durable else EVENT_QOS.durability,
    )


class RecorderNode(SuiteNode):
    """Records the suite topics (see module docstring).

    Args:
        writer: an open ``BagWriter`` to append to (``run --resume`` copies the old run into it
            first); by default one is opened on parameter ``path``.
        topics: which topics to record (default: all suite topics).
    """

    def __init__(
        self,
        *,
        context: Context | None = None,
        overrides: dict[str, Any] | None = None,
        cli_args: list[str] | None = None,
        writer: BagWriter | None = None,
        topics: Iterable[TopicSpec] = ALL_TOPICS,
    ) -> None:
        super().__init__(
            "recorder", PARAMS, context=context, overrides=overrides, cli_args=cli_args
        )
        self.topics = tuple(topics)
        if writer is None:
            path = Path(self.settings["path"])
            if not path.parent.is_dir():
                raise ParameterError("path", f"directory {path.parent} does not exist")
            writer = BagWriter(path, flush_interval_s=self.settings["flush_interval_s"])
        self.writer = writer
        self.writer.add_suite_topics(self.topics)
        self.recorded = 0
        self._subs = [
            self.create_subscription(
                spec.msg_type,
                spec.name,
                self._callback(spec.name),
                recording_qos(spec),
                raw=True,
                # no QoS-event handlers: fewer entities in every executor wait (the recorder's
                # QoS is compatible with the suite's publishers by construction)
                event_callbacks=SubscriptionEventCallbacks(use_default_callbacks=False),
            )
            for spec in self.topics
        ]
        self.state = "recording"

    def _callback(self, topic: str) -> Any:
        def record(data: bytes) -> None:
            self.writer.write_serialized(topic, data)
            self.recorded += 1

        return record

    def matched(self, topics: Iterable[str]) -> bool:
        """True when every named topic has at least one publisher matched to the recorder."""
        wanted = set(topics)
        return all(
            sub.get_publisher_count() > 0
            for spec, sub in zip(self.topics, self._subs, strict=True)
            if spec.name in wanted
        )

    def close(self) -> None:
        """Finish the bag (summary and footer)."""
        self.writer.close()


def main(argv: list[str] | None = None) -> int:
    """``ros2 run localpbo_ros recorder_node --ros-args -p path:=run.mcap``."""
    from localpbo_ros.entry import run_node

    return run_node(RecorderNode, argv, stop_when_finished=False)


if __name__ == "__main__":
    sys.exit(main())
