"""TuRPBO optimizer-only compute on one Hopper run (paper App. E; target 10x below 489 s).

One run of 495 evaluations with the paper's policy-search warm start (App. D.1: 5d = 165
random evaluations, then 10d = 330 iterations), 10 % oracle noise. Prints the optimizer's
own time (``ask``/``tell``; episodes excluded), the median per-decision latency over the
last 50 evaluations (n = 446..495) and the ratio to the paper's 489 s per run.

    python -m localpbo_core.benchmarks.turpbo_compute [--seed 0] [--out DIR] [--torch-threads 1]
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from localpbo_core.experiments.paper import PAPER_SECONDS as PAPER_SECONDS_TABLE

PAPER_SECONDS = PAPER_SECONDS_TABLE["hopper"]["turpbo"]  # App. E, 495 evaluations
DIM = 33


def main(argv: Sequence[str] | None = None) -> int:
    """Run the benchmark and print the figures."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, default=0, help="run seed")
    parser.add_argument("--out", default="turpbo_compute_out", help="where results.csv goes")
    parser.add_argument("--torch-threads", type=int, default=None, help="torch threads")
    parser.add_argument("--last", type=int, default=50, help="evaluations for the latency")
    args = parser.parse_args(argv)
    if args.torch_threads is not None:
        import torch

        torch.set_num_threads(args.torch_threads)
    from localpbo_core.bench import bench

    initial, budget = 5 * DIM, 5 * DIM + 10 * DIM
    t0 = time.perf_counter()
    records = bench(
        "hopper",
        ["turpbo"],
        [args.seed],
        Path(args.out),
        budget=budget,
        initial_design=initial,
        noise=0.1,
        progress=True,
    )
    wall = time.perf_counter() - t0
    secs = np.array([r.decision_seconds for r in records])
    total = float(secs.sum())
    last = secs[-args.last :]
    print(
        f"TuRPBO on hopper (d={DIM}), {len(records)} evaluations "
        f"({initial} initial + {budget - initial} iterations), seed {args.seed}"
    )
    print(f"optimizer-only compute per run: {total:.1f} s (wall incl. episodes {wall:.1f} s)")
    print(
        f"median per-decision latency, evaluations {len(records) - len(last) + 1}-"
        f"{len(records)}: {np.median(last):.3f} s"
    )
    print(
        f"paper (App. E): {PAPER_SECONDS:.0f} s per run; ratio paper/ours = "
        f"{PAPER_SECONDS / total:.1f}x (target >= 10x)"
    )
    print(f"final best_seen {records[-1].best_seen:.1f}, results in {Path(args.out)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
