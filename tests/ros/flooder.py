"""A hostile peer on this host: floods the suite topics with forged but well-formed messages.

Run as a process (``python tests/ros/flooder.py RUN_ID SECONDS RATE``) on the nodes' domain.
It publishes RATE messages per second (0: as fast as it can), round-robin: candidates of the
run with ids near 10**7, episode results and duel requests of the run with ids far outside its
range, messages of another run, malformed and oversized duel requests, and statuses of a node
that is not in the run. On SIGINT/SIGTERM or after SECONDS it prints how many messages it
sent and exits 0.
"""

from __future__ import annotations

import signal
import sys
import time

from localpbo_ros.dds import host_scope


def main() -> None:
    run_id, seconds, rate = sys.argv[1], float(sys.argv[2]), float(sys.argv[3])
    host_scope()  # the executables' host-only DDS, so the flood meets the nodes
    import rclpy
    from diagnostic_msgs.msg import DiagnosticStatus, KeyValue
    from rclpy.node import Node

    from localpbo_msgs_py import CandidateMsg, DuelRequest, EpisodeResult, Status
    from localpbo_msgs_py.topics import (
        CANDIDATE,
        DUEL_OUTCOME,
        DUEL_REQUEST,
        EPISODE_RESULT,
        STATUS,
    )

    stop = False

    def on_signal(signum: int, frame: object) -> None:
        nonlocal stop
        stop = True

    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, on_signal)
    rclpy.init(signal_handler_options=rclpy.signals.SignalHandlerOptions.NO)
    node = Node("flooder")
    pubs = {
        s.name: node.create_publisher(s.msg_type, s.name, s.qos)
        for s in (CANDIDATE, EPISODE_RESULT, DUEL_REQUEST, DUEL_OUTCOME, STATUS)
    }
    theta = (0.5,) * 16
    oversized = DiagnosticStatus(
        name="localpbo/duel_request", values=[KeyValue(key=f"k{i}", value="v") for i in range(65)]
    )
    sent = 0
    start = time.monotonic()
    end = start + seconds
    while not stop and time.monotonic() < end:
        if rate > 0 and sent > rate * (time.monotonic() - start):
            time.sleep(0.005)
            continue
        i = 10**7 + sent
        batch = [
            (CANDIDATE, CandidateMsg(run_id, i, theta).encode()),
            (EPISODE_RESULT, EpisodeResult.ok(run_id, i, 1e6).encode()),
            (DUEL_REQUEST, DuelRequest(run_id, i, i, i + 1).encode()),
            (DUEL_REQUEST, DuelRequest("other_run", sent % 50, 0, 1).encode()),
            (DUEL_REQUEST, oversized),
            (STATUS, Status("other_run", "intruder", "running", counters={"n": sent}).encode()),
        ]
        for spec, msg in batch:
            pubs[spec.name].publish(msg)
            sent += 1
    print(f"flooder sent {sent}", flush=True)
    node.destroy_node()
    rclpy.shutdown()


if __name__ == "__main__":
    main()
