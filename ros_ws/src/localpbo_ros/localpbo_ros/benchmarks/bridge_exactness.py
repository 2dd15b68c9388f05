"""Benchmark: are the scores ``param_bridge_node`` records each trial's own, under load?

Run: ``python -m localpbo_ros.benchmarks.bridge_exactness [--busy 4] [--budget 10]
[--modes samples,done,duration] [--domain 93]``. Prints figures; asserts nothing.

The target is :mod:`localpbo_ros.benchmarks.thermal_controller`, a free-running PID loop
written as a user writes one (it publishes a cost at every step, also between trials and after
its done message). README's command, ``localpbo run --space … --bridge …``, tunes it in each
scoring mode while ``--busy`` processes spin on the CPU beside it. Each recorded result is then
checked offline against the candidate's gains: an ``ok`` score is *exact* when it is minus the
mean cost of exactly the first ``STEPS`` steps after the reset (count and done-topic modes), or
of some prefix from the reset (duration mode: how many steps fit in the window depends on the
machine); otherwise it is *wrong*. ``failed`` results are counted with their reasons.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import tempfile
import time
from collections import Counter
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from localpbo_msgs_py import CandidateMsg, EpisodeResult
from localpbo_msgs_py.bag import read_messages
from localpbo_msgs_py.topics import CANDIDATE, EPISODE_RESULT
from localpbo_ros.benchmarks.thermal_controller import trial_costs
from localpbo_ros.dds import PROFILE_FILE

STEPS = 100
"""Control steps of one episode of the thermal controller (its ``episode_steps``)."""
SPACE = """\
name: thermal
value_range: 20.0
parameters:
  - {name: kp, lower: 0.1, upper: 50.0, log: true, initial: 1.0}
  - {name: ki, lower: 0.01, upper: 10.0, log: true, initial: 0.1}
  - {name: kd, lower: 0.0, upper: 2.0, initial: 0.1}
"""
BRIDGE = {
    "target_node": "/thermal",
    "score_topic": "/thermal/cost",
    "score_kind": "cost",
    "score_reduce": "mean",
    "reset_service": "/thermal/reset",
}
MODES: dict[str, dict[str, Any]] = {
    "samples": {"trial_samples": STEPS, "trial_duration_s": 30.0},
    "done": {"done_topic": "/thermal/done", "trial_duration_s": 30.0},
    "duration": {"trial_duration_s": 0.3},
}
"""The scoring modes: a count, the done topic, a duration."""
LOCALPBO = str(Path(sys.executable).with_name("localpbo"))


def environment(domain: int) -> dict[str, str]:
    """A user's shell on this host, set up as docs/controllers.md says."""
    skip = ("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALPBO_DDS_OPEN", "ROS_LOCALHOST_ONLY")
    env = {k: v for k, v in os.environ.items() if k not in skip}
    env["ROS_DOMAIN_ID"] = str(domain)
    env["FASTRTPS_DEFAULT_PROFILES_FILE"] = str(PROFILE_FILE)
    return env


def start_controller(env: dict[str, str], rate_hz: float = 400.0) -> subprocess.Popen[str]:
    """The thermal controller as its own process, once it is up."""
    module = "localpbo_ros.benchmarks.thermal_controller"
    proc = subprocess.Popen(
        [sys.executable, "-m", module, "--ros-args", "-p", f"rate_hz:={rate_hz}"],
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
    )
    assert proc.stdout is not None
    line = proc.stdout.readline()
    if "up" not in line:
        raise RuntimeError(f"the thermal controller did not start: {line!r}")
    return proc


@contextmanager
def busy(processes: int) -> Iterator[None]:
    """``processes`` processes spinning on the CPU while the block runs."""
    spinning = [
        subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(processes)
    ]
    try:
        yield
    finally:
        for p in spinning:
            p.kill()
            p.wait()


def recorded(bag: Path) -> tuple[dict[int, tuple[float, ...]], list[EpisodeResult]]:
    """Candidates (gains) and every episode result of a bag."""
    thetas: dict[int, tuple[float, ...]] = {}
    results: list[EpisodeResult] = []
    for rec in read_messages(bag, topics=[CANDIDATE.name, EPISODE_RESULT.name]):
        if rec.topic == CANDIDATE.name:
            cand = CandidateMsg.decode(rec.message)
            if isinstance(cand, CandidateMsg):
                thetas[cand.candidate_id] = cand.theta
        else:
            res = EpisodeResult.decode(rec.message)
            if isinstance(res, EpisodeResult):
                results.append(res)
    return thetas, results


def prefix_lengths(theta: tuple[float, ...], score: float, n: int) -> list[int]:
    """The k <= n for which minus the mean cost of the first k steps after a reset with gains
    ``theta`` is ``score`` (to rounding)."""
    out, total = [], 0.0
    kp, ki, kd = theta
    for k, c in enumerate(trial_costs(kp, ki, kd, n), 1):
        total += c
        if math.isclose(-total / k, score, rel_tol=1e-12, abs_tol=1e-12):
            out.append(k)
    return out


def is_exact(mode: str, theta: tuple[float, ...], score: float) -> bool:
    """Whether ``score`` is the trial's own (module docstring)."""
    ks = prefix_lengths(theta, score, 4 * STEPS)
    return len(ks) == 1 if mode == "duration" else ks == [STEPS]


def run_command(
    space: Path, bag: Path, mode: str, budget: int, seed: int = 1, **bridge: Any
) -> list[str]:
    """README's command for a bridged run in ``mode``."""
    return [
        LOCALPBO, "run", "--space", str(space), "--budget", str(budget), "--seed", str(seed),
        "--run-id", mode, "--bag", str(bag), "--no-progress", "--max-retries", "5",
        "--bridge", json.dumps({**BRIDGE, **MODES[mode], **bridge}),
    ]  # fmt: skip


@dataclass
class Tally:
    """What one run recorded."""

    mode: str
    exact: int
    wrong: int
    failed: Counter[str]
    seconds: float
    exit_code: int


def measure(mode: str, budget: int, domain: int, folder: Path) -> Tally:
    """Tune the thermal controller in ``mode`` and check every recorded result."""
    env = environment(domain)
    space = folder / "thermal.yaml"
    space.write_text(SPACE)
    bag = folder / f"{mode}.mcap"
    controller = start_controller(env)
    start = time.monotonic()
    try:
        done = subprocess.run(
            run_command(space, bag, mode, budget), env=env, capture_output=True, text=True
        )
    finally:
        controller.kill()
        controller.wait()
    seconds = time.monotonic() - start
    thetas, results = recorded(bag) if bag.exists() else ({}, [])
    exact = wrong = 0
    failed: Counter[str] = Counter()
    for res in results:
        if res.status.value == "failed":
            failed[res.error.split(" (")[0][:60]] += 1
        elif res.episode_return is not None and is_exact(
            mode, thetas[res.candidate_id], res.episode_return
        ):
            exact += 1
        else:
            wrong += 1
    return Tally(mode, exact, wrong, failed, seconds, done.returncode)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--busy", type=int, default=4, help="CPU-spinning processes beside")
    parser.add_argument("--budget", type=int, default=10)
    parser.add_argument("--modes", default=",".join(MODES))
    parser.add_argument("--domain", type=int, default=93)
    args = parser.parse_args(argv)
    print(f"{os.cpu_count()} cores; {args.busy} busy processes; budget {args.budget} per mode")
    print(f"{'mode':<9} {'ok exact':>8} {'ok wrong':>8} {'failed':>6}  {'s':>6}  exit  failures")
    with tempfile.TemporaryDirectory() as tmp, busy(args.busy):
        for i, mode in enumerate(args.modes.split(",")):
            t = measure(mode, args.budget, args.domain + i, Path(tmp))
            why = "; ".join(f"{n}x {k}" for k, n in t.failed.items()) or "-"
            print(
                f"{t.mode:<9} {t.exact:>8} {t.wrong:>8} {sum(t.failed.values()):>6}  "
                f"{t.seconds:>6.1f}  {t.exit_code:>4}  {why}",
                flush=True,
            )
    return 0


if __name__ == "__main__":
    sys.exit(main())
