"""Sweep scaling: the same spec of equal-cost runs with 2 Ray workers against 1.

Each run is TuRPBO on Hartmann 6 (120 evaluations, seeds 0..N-1; all runs cost about
the same, about 3 s each here). Prints the wall time of each sweep as a user sees it (Ray
start-up and shutdown included, a fresh output folder each), split into Ray's start-up, the
runs (from Ray being up to the last result, the workers' first imports included) and the
shutdown, and the ratio 1 worker / 2 workers (target >= 1.8x on a 2-core machine)::

    python -m localpbo_core.benchmarks.sweep_scaling            # 32 runs, about 2.5 minutes
    python -m localpbo_core.benchmarks.sweep_scaling --runs 16

A sweep pays a fixed cost once whatever its size (Ray's start-up and shutdown, each worker's
first imports: about 6 s here), so the ratio grows with the number of runs.
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


def timed_sweep(workers: int, runs: int, budget: int) -> tuple[float, float, float]:
    """Wall seconds of one sweep with an embedded Ray of ``workers`` CPUs: Ray's start-up,
    the runs, Ray's shutdown (what ``localpbo sweep`` does in one call, timed in parts)."""
    import ray

    from localpbo_core.sweep import start_ray, sweep

    spec = parse_spec(equal_cost_spec(runs, budget))
    with tempfile.TemporaryDirectory() as tmp:
        start = time.perf_counter()
        start_ray(None, workers)
        up = time.perf_counter()
        result = sweep(spec, Path(tmp), workers=workers, progress=False)  # uses the Ray above
        done = time.perf_counter()
        ray.shutdown()
        end = time.perf_counter()
    assert len(result.finished) == runs and not result.failed
    return up - start, done - up, end - done


def main(argv: list[str] | None = None) -> None:
    """Command-line entry point (see the module docstring)."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--runs", type=int, default=32, help="runs per sweep")
    parser.add_argument("--budget", type=int, default=120, help="evaluations per run")
    args = parser.parse_args(argv)
    one = timed_sweep(1, args.runs, args.budget)
    two = timed_sweep(2, args.runs, args.budget)
    print(f"{args.runs} equal-cost runs (TuRPBO, Hartmann 6, {args.budget} evaluations each)")
    print("           wall s   Ray start s   runs s   shutdown s")
    for name, (up, work, down) in (("1 worker ", one), ("2 workers", two)):
        print(f"{name}: {up + work + down:8.1f}   {up:11.1f}   {work:6.1f}   {down:10.1f}")
    print(f"ratio    : {sum(one) / sum(two):8.2f}x (target >= 1.8x on 2 cores)")
    print(f"runs only: {one[1] / two[1]:8.2f}x (Ray up, to the last result)")


if __name__ == "__main__":
    main()
