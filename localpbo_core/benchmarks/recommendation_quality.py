"""Benchmark: the end-of-run recommendation against the incumbent, by their true values.

For each seed, one in-process run (10% oracle noise), then the noise-free value ``f_true`` of
the incumbent (the candidate that won its latest duel), of the recommendation
(:func:`localpbo_core.optimizers.recommendation.recommend`: highest posterior mean utility
given all duels) and the best value seen. Neither choice reads a value; ``f_true`` is only
for this report.

    python -m localpbo_core.benchmarks.recommendation_quality \\
        [--problem swimmer] [--algorithm turpbo] [--seeds 0-5] [--budget 162]

A script, not a test: it prints figures and asserts nothing.
"""

from __future__ import annotations

import argparse
from collections.abc import Sequence

import numpy as np
import torch

from localpbo_core.arguments import parse_seeds
from localpbo_core.loop import run_session
from localpbo_core.problems import make_problem
from localpbo_core.session import RunSettings, Session


def main(argv: Sequence[str] | None = None) -> int:
    """Run the benchmark and print the table."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--problem", default="swimmer", help="problem name")
    parser.add_argument("--algorithm", default="turpbo", help="algorithm name")
    parser.add_argument("--seeds", default="0-5", help="seeds, e.g. 0-5 or 0,3")
    parser.add_argument("--budget", type=int, default=None, help="evaluations (default 2+10d)")
    parser.add_argument("--noise", type=float, default=0.1, help="oracle noise fraction")
    parser.add_argument("--torch-threads", type=int, default=1, help="torch threads")
    args = parser.parse_args(argv)
    torch.set_num_threads(args.torch_threads)
    problem = make_problem(args.problem)
    print(f"{args.algorithm} on {args.problem}, noise {args.noise:g}; f_true of the choices")
    print(f"{'seed':>4} {'incumbent':>10} {'recommended':>12} {'best seen':>10}")
    rows = []
    for seed in parse_seeds(args.seeds):
        settings = RunSettings(
            algorithm=args.algorithm,
            problem=args.problem,
            seed=seed,
            budget=args.budget,
            noise_fraction=args.noise,
        )
        session = Session(settings, problem)
        records = run_session(session).records
        value = {r.candidate_id: r.f_true for r in records}
        rec = session.recommendation()
        inc = session.incumbent
        assert rec is not None and inc is not None
        rows.append((value[inc.id], value[rec.id], max(value.values())))
        print(f"{seed:>4} {rows[-1][0]:>10.4g} {rows[-1][1]:>12.4g} {rows[-1][2]:>10.4g}")
    mean = np.mean(rows, axis=0)
    print(f"{'mean':>4} {mean[0]:>10.4g} {mean[1]:>12.4g} {mean[2]:>10.4g}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
