"""Benchmark: a pool of sim_node workers as separate processes, 1 worker vs N.

Run: ``python -m localpbo_ros.benchmarks.pool [--task hopper] [--workers 2] [--budget 40]
[--episode-steps 1000] [--batch-size 4] [--warm-start ars] [--domain 97]``. Prints figures;
asserts nothing.

TuRPBO with ``batch_size`` candidates per ask (each dueled against the incumbent) on Hopper
(``--task``: also ``swimmer``, whose episodes never end early, or ``walker2d``).
Hopper episodes end when the hopper falls, which a poor linear policy does within a few dozen
steps: the episodes are then short next to the serial part of a step (the optimizer's ask, the
round trips, the oracle), and a second worker gains little. ``--warm-start ars`` starts
TuRPBO from the trained ARS policy shipped in ``sims/data/ars`` (clipped to the task's box):
an existing controller, as when tuning a real one, whose neighbours mostly stay up for the
whole episode.
The oracle node and the workers (``sim_node`` renamed ``sim_<i>``) run as processes on this
host (the executables' loopback DDS profile, domain ``--domain``); the optimizer node runs in
this process, started once it hears all workers (``min_workers``). Wall time per evaluation =
(last outcome − start) / evaluations of the optimizer node; both layouts run the same
configuration and must end with the same incumbent (who evaluates never changes a run).
A short run before both, not counted, pays the optimizer process's one-time costs. The
episodes of the 1-worker run are then run again in this process and timed: they are what a
second worker takes over (with its own message handling); the optimizer's asks, its messages
and the oracle stay serial, so their share of the wall time bounds the speed-up (printed).
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


def ars_warm_start(task: str) -> list[float]:
    """θ in [0, 1]^d of the ARS policy of ``task`` (its weights clipped to the task's box)."""
    import numpy as np

    from localpbo_core.problems import make_problem
    from sims.ars import load_ars_policy

    problem = make_problem(task)
    lo = np.asarray(problem.to_native(np.zeros(problem.dim)))
    hi = np.asarray(problem.to_native(np.ones(problem.dim)))
    weights = load_ars_policy(task).weights.ravel()
    return [float(v) for v in np.clip((weights - lo) / (hi - lo), 0.0, 1.0)]


def _start(module: str, env: dict[str, str], *ros_args: str) -> subprocess.Popen[bytes]:
    cmd = [sys.executable, "-m", f"localpbo_ros.{module}"]
    if ros_args:
        cmd += ["--ros-args", *ros_args]
    return subprocess.Popen(cmd, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)


def episode_seconds(session: Any) -> float:
    """Wall seconds of all of ``session``'s evaluations, run again here one after another
    (the same episodes: each candidate's episode seed is fixed); best of 3 repetitions."""
    cands = [session.candidate(i) for i in range(session.evaluations)]
    times = []
    for _ in range(3):
        start = time.perf_counter()
        for cand in cands:
            session.evaluate(cand)
        times.append(time.perf_counter() - start)
    return min(times)


def run(
    workers: int, args: argparse.Namespace, name: str = "pool-bench"
) -> tuple[float, Any, Any, float]:
    """(wall seconds from start to the last outcome, the optimizer's session, incumbent θ,
    optimizer CPU seconds) with ``workers`` sim_node processes."""
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.logging import LoggingSeverity

    from localpbo_ros.dds import host_scope
    from localpbo_ros.optimizer_node import OptimizerNode

    host_scope()
    env = {**os.environ, "ROS_DOMAIN_ID": str(args.domain)}
    os.environ["ROS_DOMAIN_ID"] = str(args.domain)
    run_id = f"{name}-{workers}"
    helpers = [_start("oracle_node", env, "-p", f"run_id:={run_id}")]
    helpers += [
        _start("sim_node", env, "-r", f"__node:=sim_{i}", "-p", f"run_id:={run_id}")
        for i in range(workers)
    ]
    options: dict[str, Any] = {"batch_size": args.batch_size}
    if args.warm_start == "ars":
        options["warm_start"] = ars_warm_start(args.task)
    rclpy.init()
    opt = None
    try:
        opt = OptimizerNode(
            overrides={
                "run_id": run_id,
                "algorithm": ALGORITHM,
                "algorithm_options": json.dumps(options),
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
        return wall, opt.driver.session, theta, opt.cpu_seconds
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
    parser.add_argument("--warm-start", choices=("none", "ars"), default="none")
    parser.add_argument("--domain", type=int, default=97)
    parser.add_argument("--timeout", type=float, default=3600.0)
    args = parser.parse_args(argv)
    print(
        f"{ALGORITHM} q={args.batch_size} on {args.task}, {args.episode_steps}-step episodes, "
        f"budget {args.budget}, seed {args.seed}, warm start {args.warm_start}, "
        f"{os.cpu_count()} CPUs"
    )
    # both layouts run the optimizer node in this process: a first, uncounted run pays its
    # one-time costs (imports, first use of torch kernels), so neither layout is charged them
    warm_up = argparse.Namespace(**{**vars(args), "budget": min(args.budget, 12)})
    run(1, warm_up, "pool-warm-up")
    figures = {}
    for n in (1, args.workers):
        wall, session, incumbent, cpu = run(n, args)
        evals = session.evaluations
        figures[n] = (wall, evals, incumbent, session)
        print(
            f"{n} worker(s): {wall:.2f} s for {evals} evaluations, {wall / evals:.3f} s each "
            f"(optimizer process CPU {cpu:.2f} s)"
        )
    (w1, e1, i1, session1), (wn, en, i_n, _) = figures[1], figures[args.workers]
    print(f"speed-up {args.workers} vs 1 worker: {(w1 / e1) / (wn / en):.2f}x")
    print(f"same incumbent: {i1 == i_n}")
    # only the episodes (and the workers' own message handling) spread over the workers;
    # the optimizer's asks, its messages and the oracle stay serial
    ep = episode_seconds(session1)
    print(
        f"episodes alone (re-run in this process): {ep:.2f} s, {100 * ep / w1:.0f} % of the "
        f"1-worker wall time; if nothing else spread, {args.workers} workers would give "
        f"{w1 / (w1 - ep + ep / args.workers):.2f}x"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
