"""Benchmark: a pool of ``param_bridge_node`` workers, each on its own controller, 1 vs N.

Run: ``python -m localpbo_ros.benchmarks.bridge_pool [--workers 2] [--budget 26]
[--batch-size 4] [--rate-hz 100] [--steps-per-tick 3] [--episode-steps 300] [--repeats 1]
[--seed 0] [--domain 88] [--out DIR]``. Prints figures; asserts nothing.

Every node is a separate process started as a user starts them (``python -m``, the same as
``ros2 run``; DDS scope: the executables' own default, this host only, domain ``--domain``):
``recorder_node``, ``oracle_node``, and per worker ``i`` one example controller
(``pid_controller_node`` renamed ``pid_<i>``) with one ``param_bridge_node`` (renamed
``bridge_<i>``) bridging it in the example's exact mode (its ``BRIDGE_SETTINGS``: reset
service, ``trial_samples`` = one episode's cost samples). Each trial lasts ``episode_steps /
(rate_hz × steps_per_tick)`` seconds of the controller's timer (1 s by default). Then
``optimizer_node`` runs TuRPBO (``batch_size`` candidates per ask, each dueled against the
incumbent) on the example's space (``pid_space.yaml``) and waits for all ``N`` workers
(``min_workers``).

Figures, from each run's bag: wall time per evaluation (first candidate to last duel outcome,
by the recorder's clock), the speed-up, who evaluated what, and the optimizer's decision time
(the ``decision_seconds`` its duel requests carry: from the answer that completed the previous
ask to the next ask's requests, i.e. telling the answers and deciding the next batch). The
decisions are serial; with ``T_decide`` their sum and ``T_trials`` the rest of the 1-worker
run's wall time (trials and their round trips, which workers share), Amdahl's law bounds the
speed-up of ``N`` workers by ``(T_trials + T_decide) / (T_trials / N + T_decide)`` (printed
beside the measured one). Who evaluates never changes a run: the candidates, duel outcomes
and episode returns of the two bags are compared, and each bag is verified
(``localpbo replay --verify``).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import shutil
import signal
import statistics
import subprocess
import sys
import tempfile
import time
from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass, fields
from pathlib import Path
from typing import Any

ALGORITHM = "turpbo"
EXAMPLE = "localpbo_examples.pid_controller_node"


def space_file() -> Path:
    """The example's space file, next to its package in the workspace."""
    import localpbo_examples

    return Path(localpbo_examples.__file__).resolve().parents[1] / "config/pid_space.yaml"


DDS_VARIABLES = ("ROS_AUTOMATIC_DISCOVERY_RANGE", "FASTRTPS_DEFAULT_PROFILES_FILE")
"""Left to the executables: their default keeps DDS on this host."""
READY_TIMEOUT_S = 180.0
STOP_TIMEOUT_S = 60.0


@dataclass(frozen=True)
class Setup:
    """One benchmark configuration (the same for every layout)."""

    budget: int = 26
    batch_size: int = 4
    seed: int = 0
    rate_hz: float = 100.0
    steps_per_tick: int = 3
    episode_steps: int = 300
    domain: int = 88
    timeout_s: float = 1800.0

    @property
    def trial_seconds(self) -> float:
        """Nominal length of one trial: the controller's episode in wall time."""
        return self.episode_steps / (self.rate_hz * self.steps_per_tick)


@dataclass(frozen=True)
class RunFigures:
    """What one run's bag says.

    Attributes:
        workers: bridge/controller pairs in the run.
        bag: the run's bag.
        wall_s: first candidate to last duel outcome (recorder's receive times).
        evaluations: candidates of the run.
        decisions_s: the optimizer's decision time of each ask, in order.
        by_worker: evaluations per bridge node name (the worker last assigned).
        load: the 1-minute load average before and after the run.
    """

    workers: int
    bag: Path
    wall_s: float
    evaluations: int
    decisions_s: tuple[float, ...]
    by_worker: dict[str, int]
    load: tuple[float, float]

    @property
    def decide_s(self) -> float:
        """Total decision time (serial)."""
        return sum(self.decisions_s)

    @property
    def per_evaluation_s(self) -> float:
        """Wall seconds per evaluation."""
        return self.wall_s / self.evaluations


def amdahl_bound(trials_s: float, decide_s: float, workers: int) -> float:
    """Largest speed-up of ``workers`` workers when only ``trials_s`` spreads over them and
    ``decide_s`` stays serial."""
    return (trials_s + decide_s) / (trials_s / workers + decide_s)


def environment(domain: int) -> dict[str, str]:
    """This process's environment with DDS left to the executables' defaults, on ``domain``."""
    env = {k: v for k, v in os.environ.items() if k not in DDS_VARIABLES}
    env.pop("LOCALPBO_DDS_OPEN", None)
    env["ROS_DOMAIN_ID"] = str(domain)
    return env


class Node:
    """A node process with its output in a log file."""

    def __init__(self, log: Path, env: dict[str, str], module: str, *ros_args: str) -> None:
        self.log = log
        cmd = [sys.executable, "-m", module, "--ros-args", *ros_args]
        with log.open("wb") as out:
            self.popen = subprocess.Popen(cmd, env=env, stdout=out, stderr=subprocess.STDOUT)

    def text(self) -> str:
        """What the process wrote so far."""
        return self.log.read_text(errors="replace")

    def stop(self) -> int:
        """SIGINT, then wait (SIGKILL after ``STOP_TIMEOUT_S``); the exit code."""
        if self.popen.poll() is None:
            self.popen.send_signal(signal.SIGINT)
        try:
            return self.popen.wait(STOP_TIMEOUT_S)
        except subprocess.TimeoutExpired:
            self.popen.kill()
            return self.popen.wait(10)


def wait_ready(nodes: Sequence[Node], timeout_s: float = READY_TIMEOUT_S) -> None:
    """Wait until every node has logged ``<name> ready``.

    Raises:
        RuntimeError: one ended first or the wait timed out (with its output).
    """
    end = time.monotonic() + timeout_s
    waiting = list(nodes)
    while waiting:
        for node in list(waiting):
            if " ready" in node.text():
                waiting.remove(node)
            elif node.popen.poll() is not None:
                raise RuntimeError(f"{node.log.stem} ended before it was ready:\n{node.text()}")
        if waiting and time.monotonic() > end:
            raise RuntimeError(f"{waiting[0].log.stem} not ready after {timeout_s:g} s")
        time.sleep(0.05)


def bridge_args(i: int, setup: Setup) -> list[str]:
    """``--ros-args`` of bridge ``i``: the example's settings on controller ``pid_<i>``."""
    from localpbo_examples.pid_controller_node import BRIDGE_SETTINGS

    target = f"/pid_{i}"
    settings: dict[str, Any] = {
        **BRIDGE_SETTINGS,
        "target_node": target,
        "reset_service": f"{target}/reset",
        "score_topic": f"{target}/cost",
        "trial_samples": setup.episode_steps,
        "trial_duration_s": max(30.0, 10 * setup.trial_seconds),
    }
    args = ["-r", f"__node:=bridge_{i}"]
    for key, value in settings.items():
        args += ["-p", f"{key}:={value}"]
    return args


def controller_args(i: int, setup: Setup) -> list[str]:
    """``--ros-args`` of controller ``pid_<i>`` (every instance the same seed)."""
    return [
        *("-r", f"__node:=pid_{i}"),
        *("-p", f"rate_hz:={float(setup.rate_hz)}"),
        *("-p", f"steps_per_tick:={setup.steps_per_tick}"),
        *("-p", f"episode_steps:={setup.episode_steps}"),
    ]


def optimizer_args(run_id: str, workers: int, setup: Setup) -> list[str]:
    """``--ros-args`` of the optimizer: TuRPBO in batches on the example's space."""
    options = json.dumps({"batch_size": setup.batch_size})
    return [
        *("-p", f"space:={space_file()}", "-p", f"algorithm:={ALGORITHM}"),
        *("-p", f"algorithm_options:='{options}'", "-p", f"budget:={setup.budget}"),
        *("-p", f"seed:={setup.seed}", "-p", f"run_id:={run_id}"),
        *("-p", "min_subscribers:=2", "-p", f"min_workers:={workers}"),
        *("-p", "progress_every:=0"),
    ]


def run_layout(workers: int, setup: Setup, out: Path, name: str = "bridge-pool") -> RunFigures:
    """One run with ``workers`` controller/bridge pairs; its bag and logs go to ``out``.

    Raises:
        RuntimeError: a node did not start, or the optimizer did not finish the run.
    """
    out.mkdir(parents=True, exist_ok=True)
    env = environment(setup.domain)
    bag = out / f"{name}-{workers}.mcap"
    bag.unlink(missing_ok=True)

    def start(label: str, module: str, *ros_args: str) -> Node:
        return Node(out / f"{name}-{workers}.{label}.log", env, module, *ros_args)

    helpers = [
        start("recorder", "localpbo_ros.recorder_node", "-p", f"path:={bag}"),
        start("oracle", "localpbo_ros.oracle_node"),
    ]
    load0 = os.getloadavg()[0]
    optimizer: Node | None = None
    try:
        for i in range(workers):
            helpers.append(start(f"pid_{i}", EXAMPLE, *controller_args(i, setup)))
            helpers.append(
                start(f"bridge_{i}", "localpbo_ros.param_bridge_node", *bridge_args(i, setup))
            )
        wait_ready(helpers)
        optimizer = start(
            "optimizer",
            "localpbo_ros.optimizer_node",
            *optimizer_args(f"{name}-{workers}", workers, setup),
        )
        try:
            code = optimizer.popen.wait(setup.timeout_s)
        except subprocess.TimeoutExpired:
            raise RuntimeError(
                f"optimizer not done after {setup.timeout_s:g} s:\n{optimizer.text()[-3000:]}"
            ) from None
        if code != 0:
            raise RuntimeError(f"optimizer exited {code}:\n{optimizer.text()[-3000:]}")
    finally:
        if optimizer is not None:
            optimizer.stop()  # already gone unless the wait was cut short
        codes = [node.stop() for node in helpers]
    if codes[0] != 0:
        raise RuntimeError(f"recorder exited {codes[0]}:\n{helpers[0].text()[-3000:]}")
    return figures_of(bag, workers, (load0, os.getloadavg()[0]))


def figures_of(bag: Path, workers: int, load: tuple[float, float]) -> RunFigures:
    """Read one run's figures from its bag."""
    from localpbo_msgs_py import CandidateMsg, Status
    from localpbo_msgs_py.bag import read_messages
    from localpbo_msgs_py.topics import CANDIDATE, DUEL_OUTCOME, STATUS
    from localpbo_ros.bagtools import load_run

    run = load_run(bag)
    first_candidate = 0
    last_outcome = 0
    assigned: dict[int, str] = {}
    names: dict[str, str] = {}
    topics = [CANDIDATE.name, DUEL_OUTCOME.name, STATUS.name]
    for rec in read_messages(bag, topics=topics):
        if rec.topic == CANDIDATE.name:
            cand = CandidateMsg.decode(rec.message)
            if isinstance(cand, CandidateMsg) and cand.run_id == run.config.run_id:
                first_candidate = first_candidate or rec.log_time_ns
                if cand.worker:
                    assigned[cand.candidate_id] = cand.worker
        elif rec.topic == DUEL_OUTCOME.name:
            last_outcome = rec.log_time_ns
        else:
            status = Status.decode(rec.message)
            if isinstance(status, Status) and status.info.get("worker"):
                names[status.info["worker"]] = status.node
    by_worker = Counter(names.get(w, w) for w in assigned.values())
    return RunFigures(
        workers=workers,
        bag=bag,
        wall_s=(last_outcome - first_candidate) / 1e9,
        evaluations=len(run.candidates),
        decisions_s=ask_decisions(run),
        by_worker=dict(sorted(by_worker.items())),
        load=load,
    )


def ask_decisions(run: Any) -> tuple[float, ...]:
    """The decision time of each ask of a recorded run: the duel requests of one ask carry
    the same ``decision_seconds``, consecutive in duel id."""
    asks: list[float] = []
    previous: float | None = None
    for _, req in sorted(run.requests.items()):
        seconds = req.decision_seconds
        if seconds is not None and seconds != previous:
            asks.append(float(seconds))
        previous = seconds
    return tuple(asks)


def decision_cpu(bag: Path) -> tuple[float, ...]:
    """CPU seconds of each ask of the run in ``bag``, decided again in this process from the
    recorded outcomes (the same decisions: same config and outcomes give the same asks),
    after one uncounted pass that pays the imports and first uses."""
    from localpbo_ros.bagtools import load_run
    from localpbo_ros.driver import Driver

    run = load_run(bag)
    seconds: list[float] = []
    for _ in range(2):
        seconds = []
        driver = Driver(run.config)
        start = time.process_time()
        driver.ask()
        seconds.append(time.process_time() - start)
        for outcome in run.outcomes:
            if driver.done:
                break
            start = time.process_time()
            driver.offer(outcome)
            if not driver.step_open and not driver.done:
                driver.ask()
                seconds.append(time.process_time() - start)
    return tuple(seconds)


def differences(bag_a: Path, bag_b: Path) -> list[str]:
    """How two runs' candidates (θ), duel outcomes (kind, winner) and episode returns differ
    (empty: identical)."""
    from localpbo_msgs_py import EpisodeResult, EpisodeStatus
    from localpbo_msgs_py.bag import read_messages
    from localpbo_msgs_py.topics import EPISODE_RESULT
    from localpbo_ros.bagtools import load_run

    def returns(bag: Path) -> dict[int, float]:
        out: dict[int, float] = {}
        for rec in read_messages(bag, topics=[EPISODE_RESULT.name]):
            res = EpisodeResult.decode(rec.message)
            if isinstance(res, EpisodeResult) and res.status is EpisodeStatus.OK:
                out.setdefault(res.candidate_id, float(res.episode_return or 0.0))
        return out

    def outcomes(run: Any) -> dict[int, tuple[str, int | None]]:
        first: dict[int, tuple[str, int | None]] = {}
        for o in run.outcomes:
            first.setdefault(o.duel_id, (o.kind.value, o.winner_id))
        return first

    a, b = load_run(bag_a), load_run(bag_b)
    found: list[str] = []
    theta_a = {k: c.theta for k, c in a.candidates.items()}
    theta_b = {k: c.theta for k, c in b.candidates.items()}
    for what, x, y in (
        ("candidate", theta_a, theta_b),
        ("duel outcome", outcomes(a), outcomes(b)),
        ("episode return", returns(bag_a), returns(bag_b)),
    ):
        if set(x) != set(y):
            found.append(f"{what} ids differ: {sorted(set(x) ^ set(y))}")
        found += [f"{what} {k}: {x[k]} vs {y[k]}" for k in sorted(set(x) & set(y)) if x[k] != y[k]]
    return found


def _line(f: RunFigures) -> str:
    workers = ", ".join(f"{k} {v}" for k, v in f.by_worker.items()) or "unassigned"
    return (
        f"{f.workers} worker(s): {f.wall_s:6.2f} s for {f.evaluations} evaluations, "
        f"{f.per_evaluation_s:.3f} s each; decisions {f.decide_s:5.2f} s over "
        f"{len(f.decisions_s)} asks (max {max(f.decisions_s, default=0.0):.2f} s); "
        f"trials by {workers}; load {f.load[0]:.1f} -> {f.load[1]:.1f}"
    )


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=(__doc__ or "").split("\n")[0])
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--budget", type=int, default=Setup.budget)
    parser.add_argument("--batch-size", type=int, default=Setup.batch_size)
    parser.add_argument("--seed", type=int, default=Setup.seed)
    parser.add_argument("--rate-hz", type=float, default=Setup.rate_hz)
    parser.add_argument("--steps-per-tick", type=int, default=Setup.steps_per_tick)
    parser.add_argument("--episode-steps", type=int, default=Setup.episode_steps)
    parser.add_argument("--repeats", type=int, default=1, help="1 vs N pairs, alternating")
    parser.add_argument("--domain", type=int, default=Setup.domain)
    parser.add_argument("--timeout", dest="timeout_s", type=float, default=Setup.timeout_s)
    parser.add_argument("--out", type=Path, help="keep bags and logs here (default: temporary)")
    args = parser.parse_args(argv)
    setup = Setup(**{f.name: getattr(args, f.name) for f in fields(Setup)})
    out = args.out or Path(tempfile.mkdtemp(prefix="bridge-pool-"))
    n = args.workers
    print(
        f"{ALGORITHM} q={setup.batch_size} on the example's PID space, budget {setup.budget}, "
        f"seed {setup.seed}; trials of {setup.episode_steps} steps at {setup.rate_hz:g} Hz x "
        f"{setup.steps_per_tick} steps per tick = {setup.trial_seconds:.2f} s; "
        f"{platform.node()}, {os.cpu_count()} CPUs, load {os.getloadavg()[0]:.1f} at start, "
        f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}",
        flush=True,
    )
    speedups: list[float] = []
    bounds: list[float] = []
    try:
        for r in range(args.repeats):
            one = run_layout(1, setup, out, f"bridge-pool-r{r}")
            print(_line(one), flush=True)
            many = run_layout(n, setup, out, f"bridge-pool-r{r}")
            print(_line(many), flush=True)
            speedup = one.per_evaluation_s / many.per_evaluation_s
            trials = one.wall_s - one.decide_s
            bound = amdahl_bound(trials, one.decide_s, n)
            speedups.append(speedup)
            bounds.append(bound)
            print(
                f"  speed-up {n} vs 1: {speedup:.2f}x; bound from the decision time "
                f"(T_trials {trials:.2f} s, T_decide {one.decide_s:.2f} s): {bound:.2f}x",
                flush=True,
            )
            cpu = sum(decision_cpu(one.bag))
            print(
                f"  the same decisions recomputed here: {cpu:.2f} s CPU; with that as T_decide "
                f"the bound is {amdahl_bound(trials, cpu, n):.2f}x",
                flush=True,
            )
            diff = differences(one.bag, many.bag)
            print(
                "  same candidates, outcomes and episode returns: "
                + ("yes" if not diff else f"NO ({len(diff)}): " + "; ".join(diff[:5])),
                flush=True,
            )
            from localpbo_ros.replay import verify

            for f in (one, many):
                report = verify(f.bag)
                if not report.ok:
                    print(f"  {f.bag.name} does not verify: {report.format()}", flush=True)
    finally:
        if args.out is None:
            shutil.rmtree(out, ignore_errors=True)
    if len(speedups) > 1:
        print(
            f"median over {len(speedups)} pairs: speed-up {statistics.median(speedups):.2f}x, "
            f"bound {statistics.median(bounds):.2f}x"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
