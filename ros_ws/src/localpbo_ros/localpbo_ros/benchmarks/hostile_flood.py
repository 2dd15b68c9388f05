"""Benchmark: what a flood of forged messages costs the nodes (memory and time).

Two parts, both in this process (a private context, discovery off: nothing leaves it):

* **triage cost**: microseconds per message for the recorder's triage
  (:class:`~localpbo_ros.admission.RunFilter`: deserialize + decode + range check) of each
  forged kind, i.e. how many forged messages per second one core can turn away;
* **flood**: ``sim_node`` and ``oracle_node`` of a budget-40 run receive ``--messages`` forged
  but well-formed candidates, episode results and duel requests with the run's id (ids drawn
  up to 10**7, a tenth inside the run's range); printed per step: messages handled, their
  rate, the process's resident memory (VmRSS) and the sizes of the nodes' dictionaries, and
  the episodes run (a forged candidate inside the range with another θ than the run's costs
  one episode at most, per id).

Asserts nothing about time. Run: ``python -m localpbo_ros.benchmarks.hostile_flood
[--messages 40000]``.
"""

from __future__ import annotations

import argparse
import os
import time
from typing import Any

import numpy as np

from localpbo_core.settings import RunSettings
from localpbo_msgs_py import CandidateMsg, DuelRequest, EpisodeResult, RunConfig, Status, topics
from localpbo_ros.admission import RunFilter
from localpbo_ros.driver import make_run_config

RUN = "flood"


def rss_mb() -> float:
    """Resident memory of this process, MB (Linux)."""
    with open("/proc/self/status") as status:
        for line in status:
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024
    return float("nan")


def forged(rng: np.random.Generator, config: RunConfig, i: int) -> tuple[topics.TopicSpec, Any]:
    """The ``i``-th forged message: kinds in turn, ids up to 10**7 (a tenth in range)."""
    top = 2 * config.budget if rng.random() < 0.1 else 10**7
    a, b = (int(v) for v in rng.integers(0, top, size=2))
    b = b if b != a else a + 1
    theta = tuple(float(v) for v in rng.uniform(config.lower, config.upper))
    kind = i % 3
    if kind == 0:
        return topics.CANDIDATE, CandidateMsg(RUN, a, theta).encode()
    if kind == 1:
        return topics.EPISODE_RESULT, EpisodeResult.ok(RUN, a, float(rng.normal())).encode()
    return topics.DUEL_REQUEST, DuelRequest(RUN, int(rng.integers(0, top)), a, b).encode()


def triage_cost(config: RunConfig) -> None:
    """Microseconds per message of the recorder's triage, per forged kind."""
    from rclpy.serialization import deserialize_message, serialize_message

    triage = RunFilter()
    triage.classify(topics.RUN_CONFIG.name, config.encode())
    kinds: dict[str, tuple[Any, Any]] = {
        "candidate, id out of range": (topics.CANDIDATE, CandidateMsg(RUN, 10**7, config.lower)),
        "episode result, id out of range": (
            topics.EPISODE_RESULT,
            EpisodeResult.ok(RUN, 10**7, 1.0),
        ),
        "duel request, id out of range": (topics.DUEL_REQUEST, DuelRequest(RUN, 10**7, 0, 1)),
        "duel request, another run": (topics.DUEL_REQUEST, DuelRequest("other", 3, 0, 1)),
        "status, another run": (topics.STATUS, Status("other", "intruder", "running")),
    }
    print("recorder triage (deserialize + decode + range), one core:")
    for name, (spec, value) in kinds.items():
        data = serialize_message(value.encode())
        n = 3000
        t0 = time.perf_counter()
        for _ in range(n):
            reason = triage.classify(spec.name, deserialize_message(data, spec.msg_type))
        us = (time.perf_counter() - t0) / n * 1e6
        print(f"  {name:<34} {us:7.1f} us  ({1e6 / us:8.0f} msg/s)  -> {reason}")


def flood(config: RunConfig, messages: int, seed: int) -> None:
    """The flood part (see module docstring)."""
    import rclpy
    from rclpy.context import Context
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node

    from localpbo_ros.oracle_node import OracleNode
    from localpbo_ros.sim_node import SimNode

    os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "OFF"
    ctx = Context()
    rclpy.init(context=ctx)
    executor = SingleThreadedExecutor(context=ctx)
    episodes: list[int] = []

    def evaluator(c: RunConfig, cid: int, theta: np.ndarray) -> float:
        episodes.append(cid)
        return float(cid)

    sim = SimNode(context=ctx, evaluator=evaluator)
    oracle = OracleNode(context=ctx)
    probe = Node("flooder", context=ctx)
    for node in (sim, oracle):
        node.warnings.period_s = 3600.0  # one warning per reason: the log stays short
    for each in (sim, oracle, probe):
        executor.add_node(each)
    pubs = {
        s.name: probe.create_publisher(s.msg_type, s.name, s.qos)
        for s in (topics.RUN_CONFIG, topics.CANDIDATE, topics.EPISODE_RESULT, topics.DUEL_REQUEST)
    }
    end = time.monotonic() + 5
    while time.monotonic() < end and not all(p.get_subscription_count() for p in pubs.values()):
        executor.spin_once(timeout_sec=0.01)
    pubs[topics.RUN_CONFIG.name].publish(config.encode())
    while sim.run_id != RUN or oracle.run_id != RUN:
        executor.spin_once(timeout_sec=0.01)

    def idle() -> None:
        """Spin until a wait of 20 ms finds nothing to do."""
        while True:
            t = time.monotonic()
            executor.spin_once(timeout_sec=0.02)
            if time.monotonic() - t >= 0.019:
                return

    rng = np.random.default_rng(seed)
    print(f"\nflood of {messages} forged messages, run budget {config.budget}:")
    print(
        f"  {'sent':>7} {'msg/s':>7} {'RSS MB':>7}  sim θ/results  oracle results/answered/waiting"
        "  episodes"
    )
    t0 = time.perf_counter()
    base = rss_mb()
    print(f"  {0:>7} {'':>7} {base:7.1f}")
    step = max(messages // 8, 90)
    sent = 0
    while sent < messages:
        for _ in range(step // 90):  # 90 at a time: within the readers' depth of 100
            for _ in range(90):
                spec, msg = forged(rng, config, sent)
                pubs[spec.name].publish(msg)
                sent += 1
            idle()
        rate = sent / (time.perf_counter() - t0)
        print(
            f"  {sent:>7} {rate:7.0f} {rss_mb():7.1f}  {len(sim._thetas):>5}/{len(sim._results):<7}"
            f"  {len(oracle._results):>5}/{len(oracle._answered)}/{len(oracle._waiting):<14}"
            f"  {len(episodes)}"
        )
    dropped = {k: v for n in (sim, oracle) for k, v in n.counters.items() if "dropped" in k}
    print(f"  drops (sim + oracle, by key): {dropped}")
    for each in (sim, oracle, probe):
        executor.remove_node(each)
        each.destroy_node()
    executor.shutdown()
    rclpy.shutdown(context=ctx)


def main() -> None:
    """Print both parts."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--messages", type=int, default=40_000)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    settings = RunSettings("sobol", "hartmann6", seed=args.seed, budget=40)
    config = make_run_config(RUN, settings)
    triage_cost(config)
    flood(config, args.messages, args.seed)


if __name__ == "__main__":
    main()
