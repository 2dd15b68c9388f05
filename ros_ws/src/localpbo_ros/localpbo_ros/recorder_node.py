"""``recorder_node``: records every suite topic, as serialized CDR, into one MCAP bag.

Subscribes raw (no deserialization) to each topic of ``localpbo_msgs_py.topics.ALL_TOPICS``
(state topics transient-local, so the latched run config and incumbent are recorded even when
published before the recorder joined) and appends the bytes with
``BagWriter.write_serialized``; channels carry the publishers' ``offered_qos_profiles`` (the
form rosbag2 writes). The writer closes a chunk and flushes every ``flush_interval_s``, so a
killed process loses at most that much.

Bounded under hostile traffic: a message longer than ``max_message_bytes`` (default twice the
largest message any decoder accepts, ``localpbo_msgs_py.limits.MAX_MESSAGE_BYTES``) is not
recorded but counted as ``dropped_oversized``; once the bag holds ``max_bag_bytes`` (like
``ros2 bag record --max-bag-size``; 0 = no cap) no further message is recorded, each is counted
as ``dropped_bag_full``, and the bag is still closed as complete at the end. Both counters and
``recorded`` travel on ``/localpbo/status``; warnings are throttled.
"""

from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path
from typing import Any, NoReturn

from rclpy.context import Context
from rclpy.event_handler import SubscriptionEventCallbacks
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

from localpbo_msgs_py.bag import MESSAGE_OVERHEAD, BagWriter
from localpbo_msgs_py.limits import MAX_MESSAGE_BYTES
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
    Param(
        "max_message_bytes",
        2 * MAX_MESSAGE_BYTES,
        "Serialized messages longer than this are not recorded (counted as dropped_oversized). "
        f"Default: twice the largest message the decoders accept ({MAX_MESSAGE_BYTES} bytes).",
        int_range=(1024, 2**31 - 1),
    ),
    Param(
        "max_bag_bytes",
        1 << 30,
        "Stop recording once the bag holds this many bytes (later messages are counted as "
        "dropped_bag_full; the bag is closed as complete). 0 = no cap.",
        int_range=(0, 1 << 40),
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
            "recorder_node", PARAMS, context=context, overrides=overrides, cli_args=cli_args
        )
        self.topics = tuple(topics)
        if writer is None:
            path = Path(self.settings["path"])
            if not path.parent.is_dir():
                raise ParameterError("path", f"directory {path.parent} does not exist")
            writer = BagWriter(path, flush_interval_s=self.settings["flush_interval_s"])
        self.writer = writer
        self.writer.add_suite_topics(self.topics)
        self._max_message = self.settings["max_message_bytes"]
        self._max_bag = self.settings["max_bag_bytes"]
        self.bag_full = False
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

    @property
    def recorded(self) -> int:
        """Messages written to the bag."""
        return self.counters["recorded"]

    def _callback(self, topic: str) -> Any:
        def record(data: bytes) -> None:
            size = len(data)
            if size > self._max_message:
                self.drop("oversized", f"{topic}: {size} bytes > max_message_bytes")
                return
            if (
                not self.bag_full
                and self._max_bag
                and (self.writer.size_bytes + size + MESSAGE_OVERHEAD > self._max_bag)
            ):
                self.bag_full = True
                self.get_logger().warning(
                    f"bag reached max_bag_bytes={self._max_bag}: recording stops, "
                    "further messages are counted as dropped_bag_full"
                )
            if self.bag_full:
                self.counters["dropped_bag_full"] += 1
                return
            self.writer.write_serialized(topic, data)
            self.counters["recorded"] += 1

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


def main(argv: list[str] | None = None) -> NoReturn:
    """``ros2 run localpbo_ros recorder_node --ros-args -p path:=run.mcap``."""
    from localpbo_ros.entry import run_node

    run_node(RecorderNode, argv, stop_when_finished=False)


if __name__ == "__main__":
    main()
