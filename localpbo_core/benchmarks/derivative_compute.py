"""Optimizer-only compute of GIPBO, GIPBOr and PrefSQP per run (paper App. E, compute table).

Hartmann 6-D with 62 evaluations and Rosenbrock 16-D with 162 (2 + 10 d, App. D.1), 10 %
oracle noise, through ``localpbo bench``'s in-process loop. Prints the optimizer's own time
(``ask``/``tell``; function evaluations excluded), the best-seen value and the ratio to the
paper's figure. Targets: GIPBO >= 20x below the paper, PrefSQP >= 10x below, GIPBOr
at most the paper's figure. Run with one thread for comparable numbers:

    python -m localpbo_core.benchmarks.derivative_compute \
        [--problems hartmann6,rosenbrock16] [--algorithms gipbo,gipbor,prefsqp] [--seeds 0]
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from localpbo_core.experiments.paper import paper_seconds

#: Required speed-up factor over the paper.
TARGET_FACTOR = {"gipbo": 20.0, "gipbor": 1.0, "prefsqp": 10.0}
BUDGETS = {"hartmann6": 62, "rosenbrock16": 162}


def main(argv: Sequence[str] | None = None) -> int:
    """Run the benchmark and print the figures."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--problems", default="hartmann6,rosenbrock16")
    parser.add_argument("--algorithms", default="gipbo,gipbor,prefsqp")
    parser.add_argument("--seeds", default="0", help="comma-separated run seeds")
    parser.add_argument("--torch-threads", type=int, default=None, help="torch threads")
    args = parser.parse_args(argv)
    if args.torch_threads is not None:
        import torch

        torch.set_num_threads(args.torch_threads)
    from localpbo_core.bench import bench

    seeds = [int(s) for s in args.seeds.split(",")]
    algorithms = args.algorithms.split(",")
    rows = []
    for problem in args.problems.split(","):
        if problem not in BUDGETS:
            raise ValueError(f"problems: {problem!r} not in {sorted(BUDGETS)}")
        with tempfile.TemporaryDirectory() as out:
            records = bench(
                problem,
                algorithms,
                seeds,
                Path(out),
                budget=BUDGETS[problem],
                noise=0.1,
                progress=False,
            )
        for alg in algorithms:
            runs = [[r for r in records if r.algorithm == alg and r.seed == s] for s in seeds]
            secs = np.array([sum(r.decision_seconds for r in run) for run in runs])
            best = np.array([run[-1].best_seen for run in runs])
            paper = paper_seconds(problem, alg)
            assert paper is not None
            rows.append((problem, alg, secs.mean(), best.mean(), paper, paper / secs.mean()))
    head = f"{'problem':<13}{'algorithm':<10}{'ours s/run':>11}{'paper s':>9}{'speed-up':>10}"
    print(head + f"{'target':>8}  best-seen")
    for problem, alg, s, best, paper, ratio in rows:
        target = f">={TARGET_FACTOR[alg]:g}x"
        print(f"{problem:<13}{alg:<10}{s:>11.2f}{paper:>9.1f}{ratio:>9.1f}x{target:>8}  {best:.4g}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
