"""Benchmark: optimizer seconds with the default thread rule against explicit thread settings.

Each row is a fresh ``python -m localpbo_core.cli bench`` process (what a user types) with
one environment: ``plain`` leaves every thread variable unset (the default rule of
:mod:`localpbo_core.threads` applies: one thread per pool), ``OMP_NUM_THREADS=1`` is the
setting the rule reproduces, and ``OMP_NUM_THREADS=<cores>`` lets torch and the BLAS use every
core. Runs are interleaved (plain, 1, cores, plain, 1, cores, ...); the table shows the median
optimizer seconds per run (the sum of ``decision_seconds``) and the ratio to ``plain``. Also
prints the time of ``import localpbo_core`` in a fresh interpreter.

    python -m localpbo_core.benchmarks.threads_compute [--problem hartmann6] \\
        [--algorithm turpbo] [--budget 62] [--repeat 3]

A script, not a test: it prints figures and asserts nothing.
"""

from __future__ import annotations

import argparse
import csv
import os
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Sequence
from pathlib import Path

THREAD_VARIABLES = ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS")


def clean_environment() -> dict[str, str]:
    """This process's environment without any thread variable."""
    return {k: v for k, v in os.environ.items() if k not in THREAD_VARIABLES}


def optimizer_seconds(env: dict[str, str], args: argparse.Namespace, out: Path) -> float:
    """Optimizer seconds of one ``localpbo bench`` run in a fresh process."""
    cmd = [
        sys.executable,
        "-m",
        "localpbo_core.cli",
        "bench",
        "--problem",
        args.problem,
        "--algorithm",
        args.algorithm,
        "--seeds",
        str(args.seed),
        "--no-progress",
        "--out",
        str(out),
    ]
    if args.budget is not None:
        cmd += ["--budget", str(args.budget)]
    subprocess.run(cmd, env=env, check=True, capture_output=True, text=True)
    with (out / "results.csv").open() as fh:
        return sum(float(row["decision_seconds"]) for row in csv.DictReader(fh))


def import_seconds(repeat: int) -> float:
    """Median wall time of ``import localpbo_core`` in a fresh interpreter."""
    code = "import time; t = time.perf_counter(); import localpbo_core; "
    code += "print(time.perf_counter() - t)"
    times = [
        float(
            subprocess.run(
                [sys.executable, "-c", code], capture_output=True, text=True, check=True
            ).stdout
        )
        for _ in range(repeat)
    ]
    return statistics.median(times)


def main(argv: Sequence[str] | None = None) -> int:
    """Run the benchmark and print the table."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--problem", default="hartmann6")
    parser.add_argument("--algorithm", default="turpbo")
    parser.add_argument("--budget", type=int, default=None, help="default: 2 + 10 d")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--repeat", type=int, default=3, help="runs per setting (median shown)")
    args = parser.parse_args(argv)
    cores = os.cpu_count() or 1
    settings = {
        "plain (no variable)": {},
        "OMP_NUM_THREADS=1": {"OMP_NUM_THREADS": "1"},
        f"OMP_NUM_THREADS={cores}": {"OMP_NUM_THREADS": str(cores)},
    }
    seconds: dict[str, list[float]] = {name: [] for name in settings}
    start = time.monotonic()
    with tempfile.TemporaryDirectory() as tmp:
        for rep in range(args.repeat):
            for i, (name, extra) in enumerate(settings.items()):
                env = {**clean_environment(), **extra}
                out = Path(tmp) / f"{rep}-{i}"
                seconds[name].append(optimizer_seconds(env, args, out))
    print(
        f"{args.algorithm} on {args.problem}, seed {args.seed}, {cores} cores, median of "
        f"{args.repeat} interleaved runs ({time.monotonic() - start:.0f} s in all)"
    )
    print(f"{'environment':<22} {'optimizer s/run':>16} {'runs':>28} {'ratio to plain':>15}")
    base = statistics.median(seconds["plain (no variable)"])
    for name, values in seconds.items():
        med = statistics.median(values)
        runs = ", ".join(f"{v:.2f}" for v in values)
        print(f"{name:<22} {med:>16.3f} {runs:>28} {med / base:>15.2f}")
    print(f"import localpbo_core: {import_seconds(args.repeat):.3f} s (median, fresh interpreter)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
