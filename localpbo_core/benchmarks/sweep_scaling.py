"""Sweep scaling: the same spec of equal-cost runs with 2 Ray workers against 1.

Each run is TuRPBO on Hartmann 6 (24 evaluations, seeds 0..N-1; all runs cost about
the same). Prints the wall time of each sweep (Ray start-up included, a fresh output folder
each) and the ratio 1 worker / 2 workers (target >= 1.8x on a 2-core machine)::

    python -m localpbo_core.benchmarks.sweep_scaling --runs 8
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

from localpbo_core.experiments import parse_spec


def equal_cost_spec(runs: int, budget: int) -> dict:
    """A spec of ``runs`` TuRPBO runs on Hartmann 6 that differ only by seed."""
    return {
        "schema": "localpbo/experiment/v1",
        "name": "sweep_scaling",
        "seeds": list(range(runs)),
        "settings": {"budget": budget},
        "problems": [{"problem": "hartmann6"}],
        "algorithms": [{"algorithm": "turpbo"}],
    }


def timed_sweep(workers: int, runs: int, budget: int) -> float:
    """Wall seconds of one sweep with an embedded Ray of ``workers`` CPUs."""
    from localpbo_core.sweep import sweep

    spec = parse_spec(equal_cost_spec(runs, budget))
    with tempfile.TemporaryDirectory() as tmp:
        start = time.perf_counter()
        result = sweep(spec, Path(tmp), workers=workers, progress=False)
        elapsed = time.perf_counter() - start
    assert len(result.finished) == runs and not result.failed
    return elapsed


def main(argv: list[str] | None = None) -> None:
    """Command-line entry point (see the module docstring)."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--runs", type=int, default=8, help="runs per sweep")
    parser.add_argument("--budget", type=int, default=24, help="evaluations per run")
    args = parser.parse_args(argv)
    one = timed_sweep(1, args.runs, args.budget)
    two = timed_sweep(2, args.runs, args.budget)
    print(f"{args.runs} equal-cost runs (TuRPBO, Hartmann 6, {args.budget} evaluations each)")
    print(f"1 worker : {one:8.1f} s wall")
    print(f"2 workers: {two:8.1f} s wall")
    print(f"ratio    : {one / two:8.2f}x (target >= 1.8x on 2 cores)")


if __name__ == "__main__":
    main()
