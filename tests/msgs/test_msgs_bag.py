"""bag.py: rosbag2-compatible MCAP checked with two independent readers, QoS metadata, schema
text, and recovery of unfinished files (copied from a live writer, cut anywhere, SIGKILLed)."""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml
from mcap.exceptions import McapError
from mcap.reader import NonSeekingReader, make_reader
from mcap_ros2.reader import read_ros2_messages
from rclpy.serialization import deserialize_message
from rosbags.highlevel import AnyReader
from rosidl_parser.definition import AbstractNestedType, NamespacedType

from localpbo_msgs_py import topics as T
from localpbo_msgs_py.bag import BagWriter, message_class, read_messages, summarize
from localpbo_msgs_py.msgdefs import SEPARATOR, full_schema_text, msg_file_text

from ._helpers import plain
from .test_msgs_codecs import all_values

TOPIC_OF = {
    "CandidateMsg": T.CANDIDATE,
    "Incumbent": T.INCUMBENT,
    "EpisodeResult": T.EPISODE_RESULT,
    "DuelRequest": T.DUEL_REQUEST,
    "DuelOutcome": T.DUEL_OUTCOME,
    "RunConfig": T.RUN_CONFIG,
    "Status": T.STATUS,
}
ROOT = Path(__file__).resolve().parents[2]


def sample_stream(n_seeds: int = 3) -> list[tuple[str, Any, Any, int]]:
    """(topic, schema value, ROS message, log time) for every schema, several times."""
    out = []
    t = 1_700_000_000_000_000_000
    for seed in range(n_seeds):
        for value in all_values(np.random.default_rng(seed)):
            t += 1_000_003
            out.append((TOPIC_OF[type(value).__name__].name, value, value.encode(), t))
    return out


def write_bag(path: Path, stream: list[tuple[str, Any, Any, int]], **kw: Any) -> None:
    with BagWriter(path, **kw) as writer:
        writer.add_suite_topics()
        for topic, _, msg, t in stream:
            writer.write(topic, msg, log_time_ns=t)


def test_two_independent_readers_agree(tmp_path: Path) -> None:
    path = tmp_path / "run.mcap"
    stream = sample_stream()
    write_bag(path, stream)
    expected = [(topic, plain(msg, msg), t) for topic, _, msg, t in stream]

    ours = list(read_messages(path))
    assert [
        (m.topic, plain(m.message, ref), m.log_time_ns)
        for m, (_, _, ref, _) in zip(ours, stream, strict=True)
    ] == expected
    # our codecs decode what was read back into the very same values
    for m, (_, value, _, _) in zip(ours, stream, strict=True):
        assert type(value).decode(m.message, expected_run_id="run-7") == value

    via_mcap_ros2 = list(read_ros2_messages(str(path)))
    assert [
        (m.channel.topic, plain(m.ros_msg, ref), m.log_time_ns)
        for m, (_, _, ref, _) in zip(via_mcap_ros2, stream, strict=True)
    ] == expected

    with AnyReader([path]) as reader:
        via_rosbags = [
            (c.topic, plain(reader.deserialize(raw, c.msgtype), ref), t)
            for (c, t, raw), (_, _, ref, _) in zip(reader.messages(), stream, strict=True)
        ]
        types = {c.topic: c.msgtype for c in reader.connections}
    assert via_rosbags == expected
    assert types == {spec.name: spec.type_name for spec in T.ALL_TOPICS}


def test_mcap_records_follow_rosbag2_conventions(tmp_path: Path) -> None:
    path = tmp_path / "run.mcap"
    write_bag(path, sample_stream(1))
    with open(path, "rb") as f:
        reader = make_reader(f)
        header = reader.get_header()
        summary = reader.get_summary()
    assert summary is not None
    assert header.profile == "ros2"
    assert {s.name for s in summary.schemas.values()} == {s.type_name for s in T.ALL_TOPICS}
    for schema in summary.schemas.values():
        assert schema.encoding == "ros2msg"
        assert schema.data.decode() == full_schema_text(schema.name)
    by_topic = {c.topic: c for c in summary.channels.values()}
    assert set(by_topic) == {s.name for s in T.ALL_TOPICS}
    for spec in T.ALL_TOPICS:
        channel = by_topic[spec.name]
        assert channel.message_encoding == "cdr"
        (profile,) = yaml.safe_load(channel.metadata["offered_qos_profiles"])
        assert profile["reliability"] == "reliable"
        state_like = spec in (T.INCUMBENT, T.RUN_CONFIG)
        assert profile["durability"] == ("transient_local" if state_like else "volatile")
        assert profile["history"] == "keep_last"
        assert profile["depth"] == spec.qos.depth
        assert profile["deadline"] == {"sec": 9223372036, "nsec": 854775807}
        assert profile["liveliness"] == "automatic"
        assert profile["avoid_ros_namespace_conventions"] is False
    # rosbags parses the same metadata into its QoS objects
    with AnyReader([path]) as reader:
        for conn in reader.connections:
            (qos,) = conn.ext.offered_qos_profiles
            state_like = conn.topic in (T.INCUMBENT.name, T.RUN_CONFIG.name)
            assert qos.reliability.name == "RELIABLE"
            assert qos.durability.name == ("TRANSIENT_LOCAL" if state_like else "VOLATILE")
            assert qos.depth == T.TOPICS_BY_NAME[conn.topic].qos.depth


def nested_closure(type_name: str) -> set[str]:
    """Every message type reachable from ``type_name``, via rclpy's own introspection."""
    seen: set[str] = set()
    todo = [message_class(type_name)]
    while todo:
        cls = todo.pop()
        for slot in cls.SLOT_TYPES:
            inner = slot.value_type if isinstance(slot, AbstractNestedType) else slot
            if isinstance(inner, NamespacedType):
                name = f"{inner.namespaces[0]}/{inner.name}"
                if name not in seen:
                    seen.add(name)
                    todo.append(message_class(f"{inner.namespaces[0]}/msg/{inner.name}"))
    return seen


@pytest.mark.parametrize("type_name", sorted({s.type_name for s in T.ALL_TOPICS}))
def test_schema_text_is_root_then_each_dependency_once(type_name: str) -> None:
    text = full_schema_text(type_name)
    package, _, name = type_name.split("/")
    parts = text.split("\n" + SEPARATOR + "\n")
    assert parts[0] == msg_file_text(package, name)
    assert len(SEPARATOR) == 80 and set(SEPARATOR) == {"="}
    headers = []
    for part in parts[1:]:
        first, _, body = part.partition("\n")
        assert first.startswith("MSG: ") and "/msg/" not in first
        dep = first.removeprefix("MSG: ")
        dep_pkg, dep_name = dep.split("/")
        assert body == msg_file_text(dep_pkg, dep_name)
        headers.append(dep)
    assert len(headers) == len(set(headers))
    assert set(headers) == nested_closure(type_name)


def read_with_mcap_stream(path: Path) -> list[tuple[str, Any, int]]:
    """The python mcap NonSeekingReader (independent of bag.py), stopping at the truncation."""
    out = []
    with open(path, "rb") as f:
        reader = NonSeekingReader(f)
        try:
            for schema, channel, message in reader.iter_messages(log_time_order=False):
                cls = message_class(schema.name)
                out.append(
                    (channel.topic, deserialize_message(message.data, cls), message.log_time)
                )
        except (McapError, EOFError, ValueError):
            pass
    return out


def test_copy_of_live_file_is_readable(tmp_path: Path) -> None:
    """Copy the file while the writer is still open: everything flushed is there."""
    path = tmp_path / "live.mcap"
    stream = sample_stream(2)
    writer = BagWriter(path, chunk_size=1 << 20, flush_interval_s=0.02)
    try:
        writer.add_suite_topics()
        for topic, _, msg, t in stream:
            writer.write(topic, msg, log_time_ns=t)
        time.sleep(0.3)  # idle writer: the background thread must flush the open chunk
        copy = tmp_path / "copy.mcap"
        shutil.copyfile(path, copy)
    finally:
        writer.close()
    expected = [(topic, plain(msg, msg), t) for topic, _, msg, t in stream]
    got = [
        (m.topic, plain(m.message, ref), m.log_time_ns)
        for m, (_, _, ref, _) in zip(read_messages(copy), stream, strict=True)
    ]
    assert got == expected
    independent = [
        (topic, plain(msg, ref), t)
        for (topic, msg, t), (_, _, ref, _) in zip(read_with_mcap_stream(copy), stream, strict=True)
    ]
    assert independent == expected
    info = summarize(copy)
    assert not info.complete and info.message_count == len(stream)
    assert summarize(path).complete


def test_cut_anywhere_yields_a_prefix(tmp_path: Path) -> None:
    """A file cut at any byte reads without raising and yields a prefix of the messages."""
    full = tmp_path / "full.mcap"
    stream = sample_stream(2)
    write_bag(full, stream, chunk_size=256)
    data = full.read_bytes()
    expected = [(topic, plain(msg, msg), t) for topic, _, msg, t in stream]
    counts = []
    cut_path = tmp_path / "cut.mcap"
    for cut in [*range(0, len(data), max(1, len(data) // 150)), len(data) - 1]:
        cut_path.write_bytes(data[:cut])
        got = [
            (m.topic, plain(m.message, ref), m.log_time_ns)
            for m, (_, _, ref, _) in zip(read_messages(cut_path), stream, strict=False)
        ]
        assert got == expected[: len(got)]
        counts.append(len(got))
        assert summarize(cut_path).message_count == len(got)
    assert counts == sorted(counts)
    assert counts[-1] == len(stream)  # only the footer was lost
    assert len(set(counts)) > 10  # small chunks: many distinct recovery points


CHILD = r"""
import sys, time
from localpbo_msgs_py.bag import BagWriter
from localpbo_msgs_py import CandidateMsg
from localpbo_msgs_py.topics import CANDIDATE
w = BagWriter(sys.argv[1], flush_interval_s=0.05)
w.add_suite_topics()
for i in range(int(sys.argv[2])):
    w.write(CANDIDATE.name, CandidateMsg("kill", i, (float(i), 0.5)).encode())
print("written", flush=True)
time.sleep(60)
"""


@pytest.mark.timeout(60)
def test_sigkill_loses_nothing_already_flushed(tmp_path: Path) -> None:
    path = tmp_path / "killed.mcap"
    env = {
        **os.environ,
        "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]),
        "ROS_AUTOMATIC_DISCOVERY_RANGE": "OFF",
    }
    n = 500
    proc = subprocess.Popen(
        [sys.executable, "-c", CHILD, str(path), str(n)], stdout=subprocess.PIPE, env=env, text=True
    )
    try:
        assert proc.stdout is not None
        assert proc.stdout.readline().strip() == "written"
        time.sleep(0.4)  # > flush interval: the idle writer's background flush has run
        proc.send_signal(signal.SIGKILL)
        proc.wait(timeout=10)
    finally:
        if proc.poll() is None:
            proc.kill()
    ids = [int(m.message.layout.dim[0].label.rsplit("=", 1)[1]) for m in read_messages(path)]
    assert ids == list(range(n))
    info = summarize(path)
    assert not info.complete
    assert [(t.topic, t.count) for t in info.topics if t.count] == [(T.CANDIDATE.name, n)]


def test_summarize_finished_bag(tmp_path: Path) -> None:
    path = tmp_path / "run.mcap"
    stream = sample_stream(2)
    write_bag(path, stream)
    info = summarize(path)
    assert info.complete and info.truncation is None
    assert info.message_count == len(stream)
    assert info.start_ns == stream[0][3] and info.end_ns == stream[-1][3]
    counts = {t.topic: t.count for t in info.topics}
    for spec in T.ALL_TOPICS:
        assert counts[spec.name] == sum(1 for topic, *_ in stream if topic == spec.name)
    assert "file complete: yes (closed cleanly)" in info.format()


def test_writer_refuses_type_mismatch_and_use_after_close(tmp_path: Path) -> None:
    path = tmp_path / "x.mcap"
    writer = BagWriter(path)
    writer.add_topic(T.CANDIDATE.name, T.CANDIDATE.type_name, T.CANDIDATE.qos)
    with pytest.raises(ValueError, match="has type std_msgs/msg/Float64MultiArray"):
        writer.write(T.CANDIDATE.name, all_values(np.random.default_rng(0))[2].encode())
    with pytest.raises(ValueError, match="already has type"):
        writer.add_topic(T.CANDIDATE.name, "std_msgs/msg/String")
    writer.close()
    writer.close()
    with pytest.raises(ValueError, match="closed"):
        writer.flush()
