"""Benchmark: codec and recording cost per message (prints figures; asserts nothing).

Run: ``python -m localpbo_ros.benchmarks.codecs [--n 2000] [--dim 16]``.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any, Protocol

import numpy as np
from rclpy.serialization import deserialize_message, serialize_message

from localpbo_msgs_py.bag import BagWriter, read_messages
from localpbo_msgs_py.records import DuelOutcome, DuelRequest, EpisodeResult
from localpbo_msgs_py.theta import CandidateMsg
from localpbo_msgs_py.topics import CANDIDATE, DUEL_OUTCOME, DUEL_REQUEST, EPISODE_RESULT


class _Codec(Protocol):
    """A suite record: ``encode`` to a ROS message, ``decode`` (a classmethod) back."""

    def encode(self) -> Any: ...


def _per_call_us(fn: Callable[[], object], n: int) -> float:
    start = time.perf_counter()
    for _ in range(n):
        fn()
    return (time.perf_counter() - start) / n * 1e6


def main(argv: list[str] | None = None) -> None:
    """Print µs per operation for codecs, CDR, and the bag writer."""
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--n", type=int, default=2000)
    parser.add_argument("--dim", type=int, default=16)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)
    rng = np.random.default_rng(args.seed)
    theta = tuple(float(v) for v in rng.standard_normal(args.dim))
    req = DuelRequest("bench", 1, 2, 3)
    values: dict[str, tuple[str, _Codec]] = {
        "candidate": (CANDIDATE.name, CandidateMsg("bench", 7, theta)),
        "episode_result": (EPISODE_RESULT.name, EpisodeResult.ok("bench", 7, -3.25)),
        "duel_request": (DUEL_REQUEST.name, req),
        "duel_outcome": (DUEL_OUTCOME.name, DuelOutcome.decisive(req, 3)),
    }
    print(f"n={args.n} dim={args.dim}")
    print(f"{'schema':<16}{'encode':>10}{'decode':>10}{'cdr ser':>10}{'cdr de':>10}  (µs/msg)")
    for key, (_, value) in values.items():
        msg = value.encode()
        data = serialize_message(msg)
        cls = type(value)
        enc = _per_call_us(value.encode, args.n)
        msg_type = type(msg)

        def decode(m: Any = msg, c: Any = cls) -> object:
            return c.decode(m, expected_run_id="bench")

        def serialize(m: Any = msg) -> object:
            return serialize_message(m)

        def deserialize(d: bytes = data, t: type = msg_type) -> object:
            return deserialize_message(d, t)

        dec = _per_call_us(decode, args.n)
        ser = _per_call_us(serialize, args.n)
        de = _per_call_us(deserialize, args.n)
        print(f"{key:<16}{enc:>10.1f}{dec:>10.1f}{ser:>10.1f}{de:>10.1f}")
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "bench.mcap"
        msgs = [(topic, value.encode()) for topic, value in values.values()]
        with BagWriter(path) as writer:
            writer.add_suite_topics()
            start = time.perf_counter()
            for i in range(args.n):
                topic, msg = msgs[i % len(msgs)]
                writer.write(topic, msg)
            write_us = (time.perf_counter() - start) / args.n * 1e6
        size = path.stat().st_size
        start = time.perf_counter()
        count = sum(1 for _ in read_messages(path))
        read_us = (time.perf_counter() - start) / count * 1e6
    print(f"bag write (serialize + record + periodic flush): {write_us:.1f} µs/msg")
    print(
        f"bag read (stream + deserialize): {read_us:.1f} µs/msg; "
        f"{size / args.n:.0f} bytes/msg on disk"
    )
    print(
        f"recording cost per duel, assuming 5 messages (candidate, episode result, duel "
        f"request, duel outcome, incumbent): {5 * write_us / 1000:.3f} ms"
    )


if __name__ == "__main__":
    main()
