"""``recorder_node``: records every suite topic, as serialized CDR, into one MCAP bag.

Subscribes raw to each topic of ``localpbo_msgs_py.topics.ALL_TOPICS`` (state topics
transient-local, so the latched run config and incumbent are recorded even when published
before the recorder joined; event topics KEEP_ALL, see :func:`recording_qos`) and appends the
received bytes with ``BagWriter.write_serialized`` (they are deserialized only to triage
them); channels carry the publishers' ``offered_qos_profiles`` (the form rosbag2 writes). The
writer closes a chunk and flushes every ``flush_interval_s``, so a killed process loses at
most that much; a stopped one first takes its backlog (:meth:`RecorderNode.drain`).

The run's own messages are never crowded out. Each message is triaged
(:class:`localpbo_ros.admission.RunFilter`): a message of the recorded run (parameter
``run_id``, or the first valid run config's: its run id, ids in its range, θ in its box) is
written on its topic; foreign traffic (another run, malformed, ids out of range, a
conflicting config) is written under ``/localpbo/foreign/<topic>`` and only up to
``max_foreign_bytes`` (at most half of ``max_bag_bytes``), so the run always keeps the rest of
the cap. A message that arrives before any run config first makes the recorder take a run
config already waiting in its subscription (the executor serves the candidate topic before the
config topic); without one it is held (the newest ``RECORD_DEPTH`` messages, ``HOLD_BYTES``
bytes) and triaged when the config arrives; the oldest beyond the bound, and those held on
close, count as foreign (``before_run``).

Bounded under hostile traffic: a message longer than ``max_message_bytes`` (default twice the
largest message any decoder accepts, ``localpbo_msgs_py.limits.MAX_MESSAGE_BYTES``) is not
recorded (``dropped_oversized``); foreign traffic beyond its share is not recorded
(``dropped_foreign_quota``); once the bag holds ``max_bag_bytes`` (like ``ros2 bag record
--max-bag-size``; 0 = no cap) no further message is recorded (``dropped_bag_full``). Counters:
``recorded`` (the run's), ``recorded_foreign``, ``foreign_<reason>`` (foreign messages seen,
by reason) and the ``dropped_<reason>`` ones; they travel on ``/localpbo/status``, and on close
they go into the bag as its ``localpbo/recorder`` metadata record with the cap and whether it
was reached (``localpbo bag-info`` prints them). Where the bag is recorded (CPU, library
versions, code digest: :func:`localpbo_core.provenance.recording_platform`) goes into its
``localpbo/platform`` metadata record when the bag opens, so ``replay --verify`` can tell a
run re-made on another platform from a run whose config was edited. Warnings are throttled.
"""

from __future__ import annotations

import time
from collections.abc import Iterable
from pathlib import Path
from typing import Any, NoReturn, Unpack

from rclpy.event_handler import SubscriptionEventCallbacks
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.serialization import deserialize_message

from localpbo_core.provenance import recording_platform
from localpbo_msgs_py.bag import (
    MESSAGE_OVERHEAD,
    PLATFORM_METADATA,
    RECORDER_METADATA,
    BagWriter,
    foreign_topic,
)
from localpbo_msgs_py.errors import DecodeReason
from localpbo_msgs_py.limits import MAX_MESSAGE_BYTES
from localpbo_msgs_py.topics import ALL_TOPICS, EVENT_QOS, RUN_CONFIG, TopicSpec
from localpbo_ros.admission import BEFORE_RUN, RunFilter
from localpbo_ros.base import NodeOptions, SuiteNode
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
        "dropped_bag_full; bag-info says the bag is capped). 0 = no cap.",
        int_range=(0, 1 << 40),
    ),
    Param(
        "max_foreign_bytes",
        64 << 20,
        "Bytes foreign traffic (other runs, malformed, ids out of range) may take, recorded "
        "under /localpbo/foreign/...; at most half of max_bag_bytes. 0 = none recorded.",
        int_range=(0, 1 << 40),
    ),
    Param(
        "run_id",
        "",
        "The run recorded on its own topics; empty = the first valid run config received.",
    ),
]

RECORD_DEPTH = 1000
"""Messages held while no run config is known."""
HOLD_BYTES = 16 << 20
"""Bytes held while no run config is known."""
DRAIN_S = 2.0
"""On close, seconds the recorder may spend taking the messages still waiting in its
subscriptions (a recorder behind a flood has a backlog)."""


def recording_qos(spec: TopicSpec) -> QoSProfile:
    """Reliable; transient-local (its own depth) for latched topics, history KEEP_ALL for
    event topics: a KEEP_LAST reader that falls behind a flood overwrites its oldest samples,
    the run's among them, while a full KEEP_ALL reader refuses new samples and the reliable
    writers send them again later (each waits in its own writer's history; a flooding
    writer's KEEP_LAST history loses its own)."""
    durable = spec.qos.durability == DurabilityPolicy.TRANSIENT_LOCAL
    return QoSProfile(
        history=HistoryPolicy.KEEP_LAST if durable else HistoryPolicy.KEEP_ALL,
        depth=max(spec.qos.depth, 1),
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
        writer: BagWriter | None = None,
        topics: Iterable[TopicSpec] = ALL_TOPICS,
        **options: Unpack[NodeOptions],
    ) -> None:
        super().__init__("recorder_node", PARAMS, **options)
        self.topics = tuple(topics)
        if writer is None:
            path = Path(self.settings["path"])
            if not path.parent.is_dir():
                raise ParameterError("path", f"directory {path.parent} does not exist")
            writer = BagWriter(path, flush_interval_s=self.settings["flush_interval_s"])
        self.writer = writer
        self.writer.add_metadata(PLATFORM_METADATA, recording_platform())
        self.writer.add_suite_topics(self.topics)
        self._max_message = self.settings["max_message_bytes"]
        self._max_bag = self.settings["max_bag_bytes"]
        foreign = self.settings["max_foreign_bytes"]
        self.max_foreign = min(foreign, self._max_bag // 2) if self._max_bag else foreign
        self.filter = RunFilter(self.settings["run_id"])
        self.bag_full = False
        self.foreign_bytes = 0
        self._held: list[tuple[TopicSpec, bytes, int]] = []
        self._held_bytes = 0
        self._taking_config = False
        self.writer.before_close(self._finish)
        self._subs = [
            self.create_subscription(
                spec.msg_type,
                spec.name,
                self._callback(spec),
                recording_qos(spec),
                raw=True,
                # no QoS-event handlers: fewer entities in every executor wait (the recorder's
                # QoS is compatible with the suite's publishers by construction)
                event_callbacks=SubscriptionEventCallbacks(use_default_callbacks=False),
            )
            for spec in self.topics
        ]
        self._config_sub = next(
            (
                sub
                for spec, sub in zip(self.topics, self._subs, strict=True)
                if spec.name == RUN_CONFIG.name
            ),
            None,
        )
        self.state = "recording"

    @property
    def recorded(self) -> int:
        """Messages written to the bag."""
        return self.counters["recorded"]

    def _callback(self, spec: TopicSpec) -> Any:
        def record(data: bytes) -> None:
            size = len(data)
            if size > self._max_message:
                self.drop("oversized", f"{spec.name}: {size} bytes > max_message_bytes")
                return
            now = time.time_ns()
            reason = self._triage(spec, data)
            if reason == BEFORE_RUN and self._take_run_config():
                reason = self._triage(spec, data)  # the config came in beside this message
            if reason == BEFORE_RUN and size <= HOLD_BYTES:
                self._hold(spec, data, now)
                return
            self._write(spec, data, reason, now)
            config = self.filter.config
            if config is not None and self.status_run_id != config.run_id:
                self.status_run_id = config.run_id  # its own status is the run's too
            if reason is None and spec.name == RUN_CONFIG.name and self._held:
                held, self._held, self._held_bytes = self._held, [], 0
                for h_spec, h_data, h_time in held:
                    self._write(h_spec, h_data, self._triage(h_spec, h_data), h_time)

        return record

    def _hold(self, spec: TopicSpec, data: bytes, log_time: int) -> None:
        """Hold a message that came before any run config; beyond the bounds the oldest held
        go out as foreign (``before_run``): a run's first messages come just before or after
        its config, so the newest are the ones a coming config may claim."""
        self._held.append((spec, data, log_time))
        self._held_bytes += len(data)
        while len(self._held) > RECORD_DEPTH or self._held_bytes > HOLD_BYTES:
            old_spec, old_data, old_time = self._held.pop(0)
            self._held_bytes -= len(old_data)
            self._write(old_spec, old_data, BEFORE_RUN, old_time)

    def _take_run_config(self) -> bool:
        """Take the run configs already waiting in their subscription, ahead of the executor's
        order (it serves the candidate topic first): a run's first candidate and its config
        often wait side by side. True when a run config is known afterwards."""
        if self._taking_config or self._config_sub is None:
            return False
        self._taking_config = True
        try:
            self._take_waiting(RUN_CONFIG, self._config_sub, time.monotonic() + DRAIN_S)
        finally:
            self._taking_config = False
        return self.filter.config is not None

    def _triage(self, spec: TopicSpec, data: bytes) -> str | None:
        try:
            msg = deserialize_message(data, spec.msg_type)
        except Exception:  # bytes that are not a message of the topic's type
            return DecodeReason.MALFORMED.value
        return self.filter.classify(spec.name, msg)

    def _fits(self, size: int) -> bool:
        if self.bag_full:
            return False
        if self._max_bag and self.writer.size_bytes + size + MESSAGE_OVERHEAD > self._max_bag:
            self.bag_full = True
            self.get_logger().warning(
                f"bag reached max_bag_bytes={self._max_bag}: recording stops, "
                "further messages are counted as dropped_bag_full"
            )
            return False
        return True

    def _write(self, spec: TopicSpec, data: bytes, reason: str | None, log_time: int) -> None:
        """Write one message on its topic (``reason`` None: the run's) or as foreign traffic."""
        size = len(data)
        topic = spec.name
        if reason is not None:
            self.counters[f"foreign_{reason}"] += 1
            self.warn(f"foreign_{reason}", f"foreign message on {topic} ({reason})")
            if self.foreign_bytes + size + MESSAGE_OVERHEAD > self.max_foreign:
                self.counters["dropped_foreign_quota"] += 1
                return
            topic = foreign_topic(topic)
            self.writer.add_topic(topic, spec.type_name, spec.qos)
        if not self._fits(size):
            self.counters["dropped_bag_full"] += 1
            return
        self.writer.write_serialized(topic, data, log_time_ns=log_time)
        if reason is None:
            self.counters["recorded"] += 1
        else:
            self.foreign_bytes += size + MESSAGE_OVERHEAD
            self.counters["recorded_foreign"] += 1

    def _finish(self, writer: BagWriter) -> None:
        """Before the bag closes: the held messages as foreign, then the accounting record."""
        held, self._held, self._held_bytes = self._held, [], 0
        for spec, data, log_time in held:
            self._write(spec, data, BEFORE_RUN, log_time)
        record = {
            "run_id": "" if self.filter.config is None else self.filter.config.run_id,
            "max_bag_bytes": str(self._max_bag),
            "max_foreign_bytes": str(self.max_foreign),
            "bag_full": "yes" if self.bag_full else "no",
        }
        record.update({f"count.{k}": str(v) for k, v in sorted(self.counters.items())})
        writer.add_metadata(RECORDER_METADATA, record)

    def matched(self, topics: Iterable[str]) -> bool:
        """True when every named topic has at least one publisher matched to the recorder."""
        wanted = set(topics)
        return all(
            sub.get_publisher_count() > 0
            for spec, sub in zip(self.topics, self._subs, strict=True)
            if spec.name in wanted
        )

    def drain(self, seconds: float = DRAIN_S) -> int:
        """Take and record the messages waiting in the subscriptions, for at most ``seconds``;
        returns how many were taken."""
        end = time.monotonic() + seconds
        return sum(
            self._take_waiting(spec, sub, end)
            for spec, sub in zip(self.topics, self._subs, strict=True)
        )

    def _take_waiting(self, spec: TopicSpec, sub: Any, end: float) -> int:
        """Take and record the messages waiting in one subscription until ``end``
        (``time.monotonic``); returns how many were taken."""
        record = self._callback(spec)
        taken = 0
        while time.monotonic() < end:
            try:
                with sub.handle:
                    got = sub.handle.take_message(sub.msg_type, sub.raw)
            except Exception:  # the subscription is already destroyed
                break
            if got is None:
                break
            record(got[0])
            taken += 1
        return taken

    def close(self) -> None:
        """Finish the bag: the backlog (:meth:`drain`), held messages, the accounting record,
        summary and footer."""
        self.drain()
        self.writer.close()


def main(argv: list[str] | None = None) -> NoReturn:
    """``ros2 run localpbo_ros recorder_node --ros-args -p path:=run.mcap``."""
    from localpbo_ros.entry import run_node

    run_node(RecorderNode, argv, stop_when_finished=False)


if __name__ == "__main__":
    main()
