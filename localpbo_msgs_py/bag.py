"""MCAP bag writer and reader for ROS 2 messages, rosbag2 (Jazzy) compatible.

Writer: header profile ``ros2``; one schema per type, named ``pkg/msg/Type``, encoding
``ros2msg`` with the full definition text (:mod:`localpbo_msgs_py.msgdefs`); one channel per
topic, message encoding ``cdr``, metadata ``offered_qos_profiles`` (YAML,
:mod:`localpbo_msgs_py.qos_yaml`); message bytes from ``rclpy.serialization.serialize_message``.
No ``rosbag2`` metadata record is written (it is optional). Crash safety: uncompressed chunks of
at most ``chunk_size`` bytes, and every ``flush_interval_s`` the open chunk is closed and the
file flushed to the OS (by a background thread, so even an idle writer flushes), so SIGKILL
loses at most the last ``flush_interval_s`` of messages; the unfinished file is read with
:func:`read_messages`, which reads sequentially and stops cleanly at the truncation.

Foreign traffic (messages on a suite topic that are not the recorded run's: another run id,
malformed, ids outside the run's range) is kept apart, under ``/localpbo/foreign/<topic>``
(:func:`foreign_topic`), so the run's own topics hold only the run. The recorder's accounting
(what it wrote and what it did not, by reason; whether the bag reached its cap) is one MCAP
metadata record, ``localpbo/recorder``, written on close (:attr:`BagSummary.recorder`); where
it was recorded (CPU and its vector flags, library versions, code digest) is another,
``localpbo/platform``, written on open (:attr:`BagSummary.platform`), because the same run
config and outcomes re-make a model-based run bit for bit only on the same platform.
"""

from __future__ import annotations

import importlib
import os
import struct
import threading
import time
from collections.abc import Callable, Iterable, Iterator, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from types import TracebackType
from typing import Any, BinaryIO

from mcap.exceptions import McapError
from mcap.records import Channel, Footer, Header, Message, Metadata, Schema
from mcap.stream_reader import StreamReader
from mcap.writer import CompressionType, Writer
from rclpy.qos import QoSProfile
from rclpy.serialization import deserialize_message, serialize_message

from localpbo_msgs_py.msgdefs import full_schema_text, split_type_name
from localpbo_msgs_py.qos_yaml import offered_qos_yaml
from localpbo_msgs_py.topics import ALL_TOPICS, TopicSpec

PROFILE = "ros2"
SCHEMA_ENCODING = "ros2msg"
MESSAGE_ENCODING = "cdr"
QOS_METADATA_KEY = "offered_qos_profiles"
LIBRARY = "localpbo_msgs_py"
RECORD_SIZE_LIMIT = 256 * 2**20
"""Largest record the reader accepts (a corrupt length field must not allocate gigabytes)."""
MESSAGE_OVERHEAD = 31 + 16
"""Bytes an MCAP message costs besides its data: the record (opcode, length, channel,
sequence, two times) and its message-index entry."""
SUITE_PREFIX = "/localpbo/"
FOREIGN_PREFIX = "/localpbo/foreign/"
"""Foreign traffic of a suite topic ``/localpbo/<name>`` is recorded on
``/localpbo/foreign/<name>``."""
RECORDER_METADATA = "localpbo/recorder"
"""Name of the metadata record holding the recorder's accounting."""
PLATFORM_METADATA = "localpbo/platform"
"""Name of the metadata record saying where the bag was recorded (CPU, libraries, code
digest), written when the recorder opens the bag."""


def foreign_topic(topic: str) -> str:
    """Where foreign traffic of ``topic`` goes: ``/localpbo/x`` -> ``/localpbo/foreign/x``."""
    if not topic.startswith(SUITE_PREFIX) or topic.startswith(FOREIGN_PREFIX):
        raise ValueError(f"{topic} is not a suite topic")
    return FOREIGN_PREFIX + topic[len(SUITE_PREFIX) :]


def message_class(type_name: str) -> type:
    """The rclpy message class for ``pkg/msg/Type`` (imports ``pkg.msg``)."""
    package, name = split_type_name(type_name)
    module = importlib.import_module(f"{package}.msg")
    cls = getattr(module, name, None)
    if not isinstance(cls, type):
        raise ValueError(f"no message class {type_name}")
    return cls


def ros_type_name(msg_or_cls: object) -> str:
    """``pkg/msg/Type`` of an rclpy message instance or class."""
    cls = msg_or_cls if isinstance(msg_or_cls, type) else type(msg_or_cls)
    package = cls.__module__.split(".")[0]
    return f"{package}/msg/{cls.__name__}"


class BagWriter:
    """Write ROS 2 messages to one rosbag2-compatible ``.mcap`` file.

    Thread-safe: ``write`` may be called from ROS callbacks while the flush thread runs.
    Use as a context manager, or call :meth:`close` (which writes the summary and footer).
    """

    def __init__(
        self,
        path: str | os.PathLike[str],
        *,
        chunk_size: int = 16 * 1024,
        flush_interval_s: float = 0.05,
        fsync: bool = False,
        background_flush: bool = True,
        clock: Callable[[], int] = time.time_ns,
    ) -> None:
        if chunk_size < 64:
            raise ValueError(f"chunk_size must be >= 64 bytes, got {chunk_size}")
        if not flush_interval_s > 0:
            raise ValueError(f"flush_interval_s must be > 0, got {flush_interval_s}")
        self.path = Path(path)
        self._stream: BinaryIO = open(self.path, "wb")
        self._writer = Writer(self._stream, chunk_size=chunk_size, compression=CompressionType.NONE)
        self._writer.start(profile=PROFILE, library=LIBRARY)
        self._flush_interval = flush_interval_s
        self._fsync = fsync
        self._clock = clock
        self._lock = threading.Lock()
        self._schemas: dict[str, int] = {}
        self._channels: dict[str, tuple[int, str]] = {}
        self._sequence: dict[str, int] = {}
        self._dirty = False
        self._position = self._stream.tell()
        self._unflushed = 0
        self._position = 0
        self._last_flush = time.monotonic()
        self._closed = False
        self._hooks: list[Callable[[BagWriter], None]] = []
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._flush_locked()
        if background_flush:
            self._thread = threading.Thread(
                target=self._flush_loop, name="localpbo-bag-flush", daemon=True
            )
            self._thread.start()

    # ----------------------------------------------------------------- topics
    def add_topic(
        self, topic: str, type_name: str, qos: QoSProfile | Sequence[QoSProfile] | None = None
    ) -> int:
        """Register ``topic`` of ``type_name`` (``pkg/msg/Type``) once; returns the channel id.

        ``qos``: the publisher's offered profile(s), stored as ``offered_qos_profiles``.
        Re-adding a topic with the same type is a no-op; with another type it is an error.
        """
        profiles: list[QoSProfile] = (
            [] if qos is None else [qos] if isinstance(qos, QoSProfile) else list(qos)
        )
        with self._lock:
            self._check_open()
            if topic in self._channels:
                channel_id, known = self._channels[topic]
                if known != type_name:
                    raise ValueError(f"topic {topic} already has type {known}, not {type_name}")
                return channel_id
            package, name = split_type_name(type_name)
            canonical = f"{package}/msg/{name}"
            if canonical not in self._schemas:
                text = full_schema_text(canonical)
                self._schemas[canonical] = self._writer.register_schema(
                    name=canonical, encoding=SCHEMA_ENCODING, data=text.encode("utf-8")
                )
            channel_id = self._writer.register_channel(
                topic=topic,
                message_encoding=MESSAGE_ENCODING,
                schema_id=self._schemas[canonical],
                metadata={QOS_METADATA_KEY: offered_qos_yaml(profiles)},
            )
            self._channels[topic] = (channel_id, canonical)
            self._sequence[topic] = 0
            self._dirty = True
            return channel_id

    def add_suite_topics(self, topics: Iterable[TopicSpec] = ALL_TOPICS) -> None:
        """Register every topic of the suite with its default type and QoS."""
        for spec in topics:
            self.add_topic(spec.name, spec.type_name, spec.qos)

    # --------------------------------------------------------------- messages
    def write(
        self,
        topic: str,
        msg: object,
        *,
        log_time_ns: int | None = None,
        publish_time_ns: int | None = None,
    ) -> None:
        """Serialize ``msg`` to CDR and append it on ``topic`` (registered on first use)."""
        if topic not in self._channels:
            self.add_topic(topic, ros_type_name(msg))
        expected = self._channels[topic][1]
        if ros_type_name(msg) != expected:
            raise ValueError(f"topic {topic} has type {expected}, got {ros_type_name(msg)}")
        self.write_serialized(
            topic,
            serialize_message(msg),
            log_time_ns=log_time_ns,
            publish_time_ns=publish_time_ns,
        )

    def copy(self, rec: BagMessage, message: object | None = None) -> None:
        """Append a read message ``rec`` with its original times (its ``message``, or
        ``message`` in its place)."""
        self.write(
            rec.topic,
            rec.message if message is None else message,
            log_time_ns=rec.log_time_ns,
            publish_time_ns=rec.publish_time_ns,
        )

    def write_serialized(
        self,
        topic: str,
        data: bytes,
        *,
        log_time_ns: int | None = None,
        publish_time_ns: int | None = None,
    ) -> None:
        """Append already-serialized CDR bytes on a registered ``topic``."""
        with self._lock:
            self._check_open()
            if topic not in self._channels:
                raise ValueError(f"topic {topic} is not registered; call add_topic first")
            log_time = self._clock() if log_time_ns is None else log_time_ns
            publish_time = log_time if publish_time_ns is None else publish_time_ns
            if log_time < 0 or publish_time < 0:
                raise ValueError("message times must be non-negative nanoseconds")
            self._writer.add_message(
                channel_id=self._channels[topic][0],
                log_time=log_time,
                data=data,
                publish_time=publish_time,
                sequence=self._sequence[topic] % 2**32,
            )
            self._sequence[topic] += 1
            position = self._stream.tell()
            if position != self._position:  # the writer closed a full chunk into the file
                self._position = position
                self._unflushed = 0
            else:
                self._unflushed += len(data) + MESSAGE_OVERHEAD
            self._dirty = True
            if time.monotonic() - self._last_flush >= self._flush_interval:
                self._flush_locked()

    def add_metadata(self, name: str, data: dict[str, str]) -> None:
        """Append one MCAP metadata record (a name and string key/values)."""
        with self._lock:
            self._check_open()
            self._writer.add_metadata(name, dict(data))
            self._position = self._stream.tell()
            self._unflushed = 0
            self._dirty = True  # the flush thread hands it to the OS like a message

    def before_close(self, hook: Callable[[BagWriter], None]) -> None:
        """Call ``hook(self)`` when :meth:`close` begins (it may still write), once."""
        self._hooks.append(hook)

    # ---------------------------------------------------------------- flushing
    def flush(self) -> None:
        """Close the open chunk and push everything written so far to the OS."""
        with self._lock:
            self._check_open()
            self._flush_locked()

    @property
    def size_bytes(self) -> int:
        """Bytes of the file so far plus the messages of the open chunk (an upper estimate;
        closing adds the summary section: indexes and statistics)."""
        with self._lock:
            if self._closed:
                return self.path.stat().st_size
            return self._stream.tell() + self._unflushed

    def _flush_locked(self) -> None:
        self._writer.flush()
        if self._fsync:
            os.fsync(self._stream.fileno())
        self._dirty = False
        self._unflushed = 0
        self._last_flush = time.monotonic()

    def _flush_loop(self) -> None:
        while not self._stop.wait(self._flush_interval):
            with self._lock:
                if self._closed:
                    return
                if self._dirty and time.monotonic() - self._last_flush >= self._flush_interval:
                    self._flush_locked()

    def _check_open(self) -> None:
        if self._closed:
            raise ValueError(f"bag {self.path} is closed")

    def close(self) -> None:
        """Write the summary section and footer; idempotent."""
        hooks, self._hooks = self._hooks, []
        for hook in hooks:
            if not self._closed:
                hook(self)
        self._stop.set()
        if self._thread is not None:
            self._thread.join()
        with self._lock:
            if self._closed:
                return
            self._closed = True
            self._writer.finish()
            self._stream.flush()
            if self._fsync:
                os.fsync(self._stream.fileno())
            self._stream.close()

    def __enter__(self) -> BagWriter:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()


# ---------------------------------------------------------------------- reading
@dataclass(frozen=True)
class BagMessage:
    """One recorded message."""

    topic: str
    type_name: str
    message: Any
    log_time_ns: int
    publish_time_ns: int
    sequence: int


@dataclass(frozen=True)
class ChannelInfo:
    """A recorded topic."""

    topic: str
    type_name: str
    message_encoding: str
    metadata: dict[str, str]


@dataclass
class _StreamState:
    profile: str | None = None
    schemas: dict[int, Schema] = field(default_factory=dict)
    channels: dict[int, Channel] = field(default_factory=dict)
    complete: bool = False
    error: str | None = None
    whole_bytes: int = 0
    metadata: dict[str, dict[str, str]] = field(default_factory=dict)


def _iter_records(path: Path, state: _StreamState) -> Iterator[Message]:
    """Messages in file order; stops at the first truncated/corrupt record (state.error)."""
    with open(path, "rb") as stream:
        reader = StreamReader(stream, record_size_limit=RECORD_SIZE_LIMIT)
        try:
            for record in reader.records:
                state.whole_bytes = stream.tell()  # the end of the last whole record read
                if isinstance(record, Header):
                    state.profile = record.profile
                elif isinstance(record, Schema):
                    state.schemas[record.id] = record
                elif isinstance(record, Channel):
                    state.channels[record.id] = record
                elif isinstance(record, Message):
                    yield record
                elif isinstance(record, Metadata):
                    state.metadata[record.name] = dict(record.metadata)
                elif isinstance(record, Footer):
                    state.complete = True
        except (McapError, struct.error, EOFError, ValueError, UnicodeDecodeError) as exc:
            state.error = f"{type(exc).__name__}: {exc}"


def _channel_info(state: _StreamState, channel_id: int) -> ChannelInfo:
    channel = state.channels.get(channel_id)
    if channel is None:
        raise ValueError(f"message on unknown channel {channel_id}")
    schema = state.schemas.get(channel.schema_id)
    if schema is None:
        raise ValueError(f"channel {channel.topic} refers to unknown schema {channel.schema_id}")
    return ChannelInfo(channel.topic, schema.name, channel.message_encoding, dict(channel.metadata))


def read_messages(
    path: str | os.PathLike[str], *, topics: Iterable[str] | None = None
) -> Iterator[BagMessage]:
    """Yield recorded messages (decoded with rclpy) in file order.

    Works on finished files and on unfinished ones (a writer that was killed): reading stops
    at the last complete chunk. Raises ``ValueError`` for a file that is not a ``ros2`` bag.
    """
    wanted = None if topics is None else set(topics)
    state = _StreamState()
    classes: dict[str, type] = {}
    for record in _iter_records(Path(path), state):
        if state.profile != PROFILE:
            raise ValueError(f"{path}: MCAP profile is {state.profile!r}, expected {PROFILE!r}")
        info = _channel_info(state, record.channel_id)
        if wanted is not None and info.topic not in wanted:
            continue
        if info.message_encoding != MESSAGE_ENCODING:
            raise ValueError(f"{path}: topic {info.topic} is {info.message_encoding}, not cdr")
        if info.type_name not in classes:
            classes[info.type_name] = message_class(info.type_name)
        yield BagMessage(
            info.topic,
            info.type_name,
            deserialize_message(record.data, classes[info.type_name]),
            record.log_time,
            record.publish_time,
            record.sequence,
        )


@dataclass(frozen=True)
class TopicSummary:
    """Per-topic figures of :func:`summarize`."""

    topic: str
    type_name: str
    count: int
    offered_qos_profiles: str


@dataclass(frozen=True)
class BagSummary:
    """What ``bag-info`` prints: topics, types, counts, time span, whether the file is whole."""

    path: str
    topics: tuple[TopicSummary, ...]
    message_count: int
    start_ns: int | None
    end_ns: int | None
    complete: bool
    truncation: str | None
    recorder: dict[str, str] = field(default_factory=dict)
    """The recorder's accounting (metadata record ``localpbo/recorder``; empty when the
    recorder was killed or the bag was written otherwise): ``max_bag_bytes``,
    ``max_foreign_bytes``, ``bag_full`` (``yes``/``no``) and ``count.<name>`` entries."""
    platform: dict[str, str] = field(default_factory=dict)
    """Where the bag was recorded (metadata record ``localpbo/platform``; empty for bags
    recorded before bags carried it or written otherwise)."""
    whole_bytes: int | None = None
    """Where the last whole record ends (None: not measured)."""
    size_bytes: int = 0
    """The file's size."""

    @property
    def duration_s(self) -> float:
        """Span between first and last log time, seconds (0 when empty)."""
        if self.start_ns is None or self.end_ns is None:
            return 0.0
        return (self.end_ns - self.start_ns) / 1e9

    def format(self) -> str:
        """Human-readable multi-line text."""
        if self.complete:
            whole = "yes (closed cleanly)"
        elif self.whole_bytes is not None and self.whole_bytes < self.size_bytes:
            whole = (
                f"no: the file ends early, cut inside a record at byte {self.whole_bytes} of "
                f"{self.size_bytes} (the messages before it are read)"
            )
        else:
            whole = "no: unfinished (no footer: the writer was stopped before closing it)"
        lines = [
            f"file:      {self.path}",
            f"file complete: {whole}",
            f"messages:  {self.message_count}",
            f"duration:  {self.duration_s:.3f} s",
        ]
        if self.start_ns is not None:
            lines.append(f"start/end: {self.start_ns} .. {self.end_ns} ns")
        if self.platform:
            p = self.platform
            lines.append(
                f"recorded on: {p.get('cpu', '?')} ({p.get('cpu_flags', '?')}), "
                f"torch {p.get('libraries.torch', '?')}, code {p.get('code.digest', '?')}"
            )
        lines.extend(self.recorder_lines())
        lines.append("topics:")
        width = max((len(t.topic) for t in self.topics), default=0)
        for t in self.topics:
            lines.append(f"  {t.topic:<{width}}  {t.type_name:<40} {t.count:>8}")
        return "\n".join(lines)

    def recorder_counts(self) -> dict[str, int]:
        """The recorder's counters (``count.<name>`` of :attr:`recorder`)."""
        return {
            k.removeprefix("count."): int(v)
            for k, v in self.recorder.items()
            if k.startswith("count.") and v.isdigit()
        }

    def recorder_lines(self) -> list[str]:
        """What the recorder wrote and did not write (empty without its record)."""
        if not self.recorder:
            return []
        counts = self.recorder_counts()
        not_written = {
            k.removeprefix("dropped_"): v
            for k, v in counts.items()
            if k.startswith("dropped_") and v
        }
        lines = [
            f"recorder:  {counts.get('recorded', 0)} run messages, "
            f"{counts.get('recorded_foreign', 0)} foreign messages recorded"
        ]
        if not_written:
            shown = ", ".join(f"{k} {v}" for k, v in sorted(not_written.items()))
            lines.append(f"not recorded: {sum(not_written.values())} ({shown})")
        foreign = {
            k.removeprefix("foreign_"): v for k, v in counts.items() if k.startswith("foreign_")
        }
        if foreign:
            shown = ", ".join(f"{k} {v}" for k, v in sorted(foreign.items()))
            lines.append(f"foreign:   {sum(foreign.values())} messages ({shown})")
        if self.recorder.get("bag_full") == "yes":
            cap = self.recorder.get("max_bag_bytes", "?")
            lost = counts.get("dropped_bag_full", 0)
            lines.append(f"capped at {cap} bytes: {lost} messages not recorded")
        return lines


def summarize(path: str | os.PathLike[str]) -> BagSummary:
    """Count messages per topic and the time span by reading the file sequentially."""
    path_size = os.path.getsize(path)
    state = _StreamState()
    counts: dict[int, int] = {}
    start: int | None = None
    end: int | None = None
    total = 0
    for record in _iter_records(Path(path), state):
        counts[record.channel_id] = counts.get(record.channel_id, 0) + 1
        total += 1
        start = record.log_time if start is None else min(start, record.log_time)
        end = record.log_time if end is None else max(end, record.log_time)
    if state.profile is not None and state.profile != PROFILE:
        raise ValueError(f"{path}: MCAP profile is {state.profile!r}, expected {PROFILE!r}")
    topics = []
    for channel_id in sorted(state.channels):
        info = _channel_info(state, channel_id)
        topics.append(
            TopicSummary(
                info.topic,
                info.type_name,
                counts.get(channel_id, 0),
                info.metadata.get(QOS_METADATA_KEY, ""),
            )
        )
    summary = BagSummary(
        str(path),
        tuple(topics),
        total,
        start,
        end,
        state.complete,
        state.error,
        state.metadata.get(RECORDER_METADATA, {}),
    )
    summary = replace(
        summary,
        platform=state.metadata.get(PLATFORM_METADATA, {}),
        whole_bytes=state.whole_bytes,
        size_bytes=path_size,
    )
    return summary
