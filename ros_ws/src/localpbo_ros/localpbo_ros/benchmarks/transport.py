"""Benchmark: time per duel over ROS topics vs in-process, and recording cost per message.

Run: ``python -m localpbo_ros.benchmarks.transport [--algorithm sobol] [--budget 60] [--seed 0]``.
Prints figures; asserts nothing. For each task (``hartmann6``: a cheap function, so the
transport cost is visible; ``swimmer``: the small MuJoCo task) the same optimizer, task and
seed run three ways:

* in-process: ``localpbo_core.loop.run_session`` (the reference loop). Its reporting call
  ``true_value`` (5 extra episodes per candidate on MuJoCo tasks) is replaced by a constant so
  both sides do the same work: one episode per candidate, one comparison per duel;
* ROS, no recorder: optimizer, simulator and oracle nodes in one process over topics;
* ROS + recorder: the same plus the MCAP recorder (``localpbo run``).

Time per duel = loop time (first ask to last outcome) / duels, median of ``--repeat``
interleaved runs. The recording cost per message
is measured directly (``BagWriter.write_serialized`` of the suite's recorded CDR messages) and
as the difference of the two ROS runs divided by the messages recorded.
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np
from mcap.reader import make_reader

from localpbo_core.loop import run_session
from localpbo_core.problems import make_problem
from localpbo_core.session import Session
from localpbo_core.settings import RunSettings
from localpbo_msgs_py.bag import BagWriter
from localpbo_ros.suite import run_suite


class _NoReporting:
    """A problem whose reporting-only ``true_value`` is free (see module docstring)."""

    def __init__(self, problem: Any) -> None:
        self._p = problem
        self.name, self.dim, self.value_range = problem.name, problem.dim, problem.value_range

    def to_native(self, theta: np.ndarray) -> np.ndarray:
        return self._p.to_native(theta)

    def evaluate(self, theta: np.ndarray, seed: int) -> float:
        return self._p.evaluate(theta, seed)

    def evaluate_native(self, x: np.ndarray, seed: int) -> float:
        return self._p.evaluate_native(x, seed)

    def true_value(self, theta: np.ndarray) -> float:
        return 0.0


def in_process(task: str, algorithm: str, budget: int, seed: int) -> tuple[float, float, int]:
    """(wall seconds, process CPU seconds, duels) of the in-process loop."""
    settings = RunSettings(algorithm=algorithm, problem=task, seed=seed, budget=budget)
    session = Session(settings, _NoReporting(make_problem(task)))
    start, cpu = time.perf_counter(), time.process_time()
    run_session(session)
    wall, cpu = time.perf_counter() - start, time.process_time() - cpu
    return wall, cpu, session.n_duels


def over_ros(task: str, algorithm: str, budget: int, seed: int, bag: Path | None) -> Any:
    """The run summary of the ROS loop (recorded iff ``bag``)."""
    settings = {
        "task": task,
        "algorithm": algorithm,
        "budget": budget,
        "seed": seed,
        "run_id": f"bench-{task}",
        "task_options": json.dumps({}),
    }
    return run_suite(
        settings,
        bag if bag is not None else Path("unused.mcap"),
        record=bag is not None,
        timeout_s=600,
    )


def write_cost_us(bag: Path, repeat: int = 5) -> float:
    """µs per message to append the bag's own CDR messages to a fresh BagWriter."""
    with open(bag, "rb") as f:
        reader = make_reader(f)
        msgs = [(ch.topic, m.data) for _, ch, m in reader.iter_messages()]
    with tempfile.TemporaryDirectory() as tmp:
        with BagWriter(Path(tmp) / "w.mcap") as writer:
            writer.add_suite_topics()
            start = time.perf_counter()
            for _ in range(repeat):
                for topic, data in msgs:
                    writer.write_serialized(topic, data)
            elapsed = time.perf_counter() - start
    return elapsed / (repeat * len(msgs)) * 1e6


def _row(
    task: str,
    clock: str,
    duels: int,
    t_in: float,
    t_bare: float,
    t_rec: float,
    recorded: float,
    write_us: float,
) -> str:
    ms_in, ms_bare, ms_rec = (t / duels * 1e3 for t in (t_in, t_bare, t_rec))
    per_msg = (t_rec - t_bare) / recorded * 1e6
    return (
        f"{task:<10}{clock:<6}{duels:>6}{ms_in:>12.2f}{ms_bare:>10.2f}{ms_rec:>10.2f}"
        f"{ms_rec - ms_in:>11.2f}{recorded / duels:>10.1f}{per_msg:>10.1f}{write_us:>10.1f}"
    )


def main(argv: list[str] | None = None) -> None:
    """Print the comparison table."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--algorithm", default="sobol")
    parser.add_argument("--budget", type=int, default=60)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--tasks", nargs="+", default=["hartmann6", "swimmer"])
    parser.add_argument("--repeat", type=int, default=3, help="runs per setting (median shown)")
    args = parser.parse_args(argv)
    print(
        f"algorithm={args.algorithm} budget={args.budget} seed={args.seed} "
        f"(median of {args.repeat} interleaved runs)"
    )
    print(
        f"{'task':<10}{'clock':<6}{'duels':>6}{'in-process':>12}{'ROS':>10}{'ROS+rec':>10}"
        f"{'overhead':>11}{'msgs/duel':>10}{'rec/msg':>10}{'write/msg':>10}"
    )
    print(
        f"{'':<22}{'ms/duel':>12}{'ms/duel':>10}{'ms/duel':>10}{'ms/duel':>11}{'':>10}"
        f"{'µs':>10}{'µs':>10}"
    )
    with tempfile.TemporaryDirectory() as tmp:
        for task in args.tasks:
            bag = Path(tmp) / f"{task}.mcap"
            runs: dict[str, list[float]] = {
                k: []
                for k in ("in_wall", "in_cpu", "bare_wall", "bare_cpu", "rec_wall", "rec_cpu", "n")
            }
            duels = 0
            for _ in range(args.repeat):  # interleaved, so load changes hit all three alike
                wall, cpu, duels = in_process(task, args.algorithm, args.budget, args.seed)
                bare = over_ros(task, args.algorithm, args.budget, args.seed, None)
                rec = over_ros(task, args.algorithm, args.budget, args.seed, bag)
                assert bare.duels == rec.duels == duels, (bare.duels, rec.duels, duels)
                for key, value in (
                    ("in_wall", wall),
                    ("in_cpu", cpu),
                    ("bare_wall", bare.loop_seconds),
                    ("bare_cpu", bare.loop_cpu_seconds),
                    ("rec_wall", rec.loop_seconds),
                    ("rec_cpu", rec.loop_cpu_seconds),
                    ("n", rec.recorded),
                ):
                    runs[key].append(value)
            med = {k: float(np.median(v)) for k, v in runs.items()}
            write_us = write_cost_us(bag)
            for clock in ("wall", "cpu"):
                print(
                    _row(
                        task,
                        clock,
                        duels,
                        med[f"in_{clock}"],
                        med[f"bare_{clock}"],
                        med[f"rec_{clock}"],
                        med["n"],
                        write_us,
                    )
                )
    print(
        "wall: elapsed time; cpu: process CPU time (all threads, insensitive to other load).\n"
        "overhead = ROS+rec − in-process per duel (target < 5 ms); rec/msg = (ROS+rec − ROS) "
        "/ messages recorded; write/msg = BagWriter.write_serialized alone."
    )


if __name__ == "__main__":
    main()
