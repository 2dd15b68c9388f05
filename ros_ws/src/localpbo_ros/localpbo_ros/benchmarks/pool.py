"""Benchmark: a pool of sim_node workers as separate processes, 1 worker vs N.

Run: ``python -m localpbo_ros.benchmarks.pool [--task hopper] [--workers 2] [--budget 40]
[--episode-steps 1000] [--batch-size 4] [--domain 97]``. Prints figures; asserts nothing.

TuRPBO with ``batch_size`` candidates per ask (each dueled against the incumbent) on Hopper
(``--task``: also ``swimmer``, whose episodes never end early, or ``walker2d``).
Hopper episodes end when the hopper falls, which a poor linear policy does within a few dozen
steps: the episodes are then short next to the serial part of a step (the optimizer's ask, the
round trips, the oracle), and a second worker gains little.
The oracle node and the workers (``sim_node`` renamed ``sim_<i>``) run as processes on this
host (the executables' loopback DDS profile, domain ``--domain``); the optimizer node runs in
this process, started once it hears all workers (``min_workers``). Wall time per evaluation =
(last outcome − start) / evaluations of the optimizer node; both layouts run the same
configuration and must end with the same incumbent (who evaluates never changes a run).
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import subprocess
import sys
import time
from typing import Any

ALGORITHM = "turpbo"
DEFAULT_TASK = "hopper"
FULL_STEPS = 1000


def task_options(task: str, steps: int) -> dict[str, Any]:
    """The task cut to ``steps`` steps; a shortened task needs a value range for the oracle
    noise (the full task's, scaled by the episode length)."""
    if steps == FULL_STEPS:
        return {}
    from localpbo_core.problems import make_problem

    full = make_problem(task).value_range
    return {"episode_steps": steps, "value_range": full * steps / FULL_STEPS}


def _start(module: str, env: dict[str, str], *ros_args: str) -> subprocess.Popen[bytes]:
    cmd = [sys.executable, "-m", f"localpbo_ros.{module}"]
    if ros_args:
        cmd += ["--ros-args", *ros_args]
    return subprocess.Popen(cmd, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)


def run(workers: int, args: argparse.Namespace) -> tuple[float, int, Any, float]:
    """(wall seconds from start to the last outcome, evaluations, incumbent θ, optimizer CPU
    seconds) with ``workers`` sim_node processes."""
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.logging import LoggingSeverity

    from localpbo_ros.dds import host_scope
    from localpbo_ros.optimizer_node import OptimizerNode

    host_scope()
    env = {**os.environ, "ROS_DOMAIN_ID": str(args.domain)}
    os.environ["ROS_DOMAIN_ID"] = str(args.domain)
    run_id = f"pool-bench-{workers}"
    helpers = [_start("oracle_node", env, "-p", f"run_id:={run_id}")]
    helpers += [
        _start("sim_node", env, "-r", f"__node:=sim_{i}", "-p", f"run_id:={run_id}")
        for i in range(workers)
    ]
    rclpy.init()
    opt = None
    try:
        opt = OptimizerNode(
            overrides={
                "run_id": run_id,
                "algorithm": ALGORITHM,
                "algorithm_options": json.dumps({"batch_size": args.batch_size}),
                "task": args.task,
                "task_options": json.dumps(task_options(args.task, args.episode_steps)),
                "budget": args.budget,
                "seed": args.seed,
                "min_subscribers": 1,
                "min_workers": workers,
                "worker_timeout_s": 120.0,
                "progress_every": 0,
            }
        )
        opt.get_logger().set_level(LoggingSeverity.WARN)
        executor = SingleThreadedExecutor()
        executor.add_node(opt)
        deadline = time.monotonic() + args.timeout
        while not opt.finished and time.monotonic() < deadline:
            executor.spin_once(timeout_sec=0.05)
        if not opt.finished or opt.error:
            raise RuntimeError(
                f"run with {workers} worker(s) ended {opt.state}: {opt.error} "
                f"({opt.pool.live(time.monotonic())} heard, {dict(opt.counters)})"
            )
        wall = opt.finished_at - opt.started_at
        theta = opt.summary().incumbent_theta
        return wall, opt.driver.session.evaluations, theta, opt.cpu_seconds
    finally:
        if opt is not None:
            opt.destroy_node()
        if rclpy.ok():
            rclpy.shutdown()
        for proc in helpers:
            proc.send_signal(signal.SIGINT)
        for proc in helpers:
            try:
                proc.wait(60)
            except subprocess.TimeoutExpired:  # a loaded machine: do not lose the figures
                proc.kill()
                proc.wait(10)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--task", default=DEFAULT_TASK, choices=("hopper", "swimmer", "walker2d"))
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--budget", type=int, default=40)
    parser.add_argument("--batch-size", type=int, default=4)
    parser.add_argument("--episode-steps", type=int, default=1000)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--domain", type=int, default=97)
    parser.add_argument("--timeout", type=float, default=3600.0)
    args = parser.parse_args(argv)
    print(
        f"{ALGORITHM} q={args.batch_size} on {args.task}, {args.episode_steps}-step episodes, "
        f"budget {args.budget}, seed {args.seed}, {os.cpu_count()} CPUs"
    )
    figures = {}
    for n in (1, args.workers):
        wall, evals, incumbent, cpu = run(n, args)
        figures[n] = (wall, evals, incumbent)
        print(
            f"{n} worker(s): {wall:.2f} s for {evals} evaluations, {wall / evals:.3f} s each "
            f"(optimizer process CPU {cpu:.2f} s: the serial part)"
        )
    (w1, e1, i1), (wn, en, i_n) = figures[1], figures[args.workers]
    print(f"speed-up {args.workers} vs 1 worker: {(w1 / e1) / (wn / en):.2f}x")
    print(f"same incumbent: {i1 == i_n}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
