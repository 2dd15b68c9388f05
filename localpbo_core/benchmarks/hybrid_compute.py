"""Decision time of the hybrid against TuRPBO at the same number of evaluations n.

Runs both algorithms in-process (the loop of ``localpbo bench``: optimizer, evaluation,
noisy duel; 10 % noise) on one problem and the same seeds, and prints the optimizer's mean
decision time per evaluation (``ask`` and the ``tell`` charged to it, episodes excluded) in
windows of n (thirds of the iterations after the initial design), the ratio hybrid/TuRPBO
per window, and the hybrid's mean time per global and per local ask. A global ask of the
hybrid is TuRPBO's plus the handover check (the gradient, its posterior covariance and, for
Newton steps, the Hessian at the center); a local ask fits the model and takes one step.

    python -m localpbo_core.benchmarks.hybrid_compute [--problem hartmann6] [--seeds 0-2]
        [--algorithm hybrid] [--option KEY=VALUE ...] [--problem-options JSON]
        [--budget N] [--out FILE]

``--algorithm`` names the hybrid or one of its presets (``hybrid_c0.5``). ``--out FILE``
also writes the figures (the ask counts over all seeds), the command, the machine and the
date as JSON; the results page
reads every ``docs/diagnosis/hybrid_compute*.json`` for the hybrid's decision-time goal
(:mod:`localpbo_core.experiments.beyond`). Asserts nothing.
"""

from __future__ import annotations

import argparse
import itertools
import json
import os
import platform
import shlex
import sys
import time
from collections.abc import Sequence
from datetime import UTC, datetime
from pathlib import Path

import numpy as np

from localpbo_core.loop import run_session
from localpbo_core.optimizers.hybrid import MODES
from localpbo_core.session import Session
from localpbo_core.settings import RunSettings
from localpbo_core.threads import use_fast_threads


def _seeds(text: str) -> list[int]:
    out: list[int] = []
    for part in text.split(","):
        lo, _, hi = part.partition("-")
        out.extend(range(int(lo), int(hi or lo) + 1))
    return out


def _option(text: str) -> tuple[str, object]:
    key, sep, raw = text.partition("=")
    if not sep:
        raise argparse.ArgumentTypeError(f"expected KEY=VALUE, got {text!r}")
    value: object = raw
    for cast in (int, float):
        try:
            value = cast(raw)
            break
        except ValueError:
            continue
    return key, value


def _run(
    problem: str,
    algorithm: str,
    seed: int,
    options: dict[str, object],
    budget: int | None,
    problem_options: dict[str, object],
) -> tuple[np.ndarray, list[str]]:
    """Per-evaluation decision seconds after the initial design, and the hybrid's modes."""
    settings = RunSettings(
        algorithm=algorithm,
        problem=problem,
        problem_options=problem_options,
        seed=seed,
        noise_fraction=0.1,
        budget=budget,
        optimizer_options=options,
    )
    session = Session(settings)
    records = run_session(session).records
    init = session.optimizer.initial_design
    secs = np.array([r.decision_seconds for r in records[init:]])
    return secs, list(getattr(session.optimizer, "modes", []))


def main(argv: Sequence[str] | None = None) -> int:
    """Run the benchmark and print the figures."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--problem", default="hartmann6")
    parser.add_argument("--seeds", default="0-2", help="e.g. 0-2 or 0,3")
    parser.add_argument(
        "--algorithm", default="hybrid", help="the hybrid or one of its presets, e.g. hybrid_c0.5"
    )
    parser.add_argument("--option", type=_option, action="append", default=[])
    parser.add_argument(
        "--problem-options", type=json.loads, default={}, help="JSON, e.g. '{\"dim\": 32}'"
    )
    parser.add_argument("--budget", type=int, default=None, help="default: the paper's")
    parser.add_argument("--out", default=None, help="also write the figures as JSON here")
    args = parser.parse_args(argv)
    use_fast_threads()
    options = dict(args.option)
    seeds = _seeds(args.seeds)
    per: dict[str, list[np.ndarray]] = {"turpbo": [], "hybrid": []}
    by_mode: dict[str, list[float]] = {m: [] for m in MODES}  # seconds of the hybrid's asks
    t0 = time.perf_counter()
    for seed in seeds:
        for algorithm in ("turpbo", "hybrid"):
            name, opts = (args.algorithm, options) if algorithm == "hybrid" else ("turpbo", {})
            secs, modes = _run(args.problem, name, seed, opts, args.budget, args.problem_options)
            per[algorithm].append(secs)
            if algorithm == "hybrid" and len(modes) == len(secs):  # q = 1: one per ask
                for s, m in zip(secs, modes, strict=True):
                    by_mode[m].append(float(s))
    n_iter = min(min(len(s) for s in v) for v in per.values())
    wall = time.perf_counter() - t0
    print(
        f"{args.problem}, seeds {seeds}, {n_iter} iterations after the initial design, "
        f"{args.algorithm} options {options or 'default'} ({wall:.0f} s wall)"
    )
    print(f"{'evaluations after init':>24} {'turpbo s':>10} {'hybrid s':>10} {'ratio':>7}")
    edges = np.linspace(0, n_iter, 4).astype(int)
    thirds = []
    for lo, hi in itertools.pairwise(edges):
        tr = float(np.mean([s[lo:hi].mean() for s in per["turpbo"]]))
        hy = float(np.mean([s[lo:hi].mean() for s in per["hybrid"]]))
        thirds.append({"evaluations": [int(lo) + 1, int(hi)], "turpbo": tr, "hybrid": hy})
        print(f"{f'{lo + 1}-{hi}':>24} {tr:10.4f} {hy:10.4f} {hy / tr:7.2f}")
    tr_all = float(np.mean([s[:n_iter].sum() for s in per["turpbo"]]))
    hy_all = float(np.mean([s[:n_iter].sum() for s in per["hybrid"]]))
    print(f"{'whole run (s per run)':>24} {tr_all:10.2f} {hy_all:10.2f} {hy_all / tr_all:7.2f}")
    for mode in ("global", "local", "probe"):
        if by_mode[mode]:
            label = f"hybrid {mode} asks:"
            print(f"{label:<20}{len(by_mode[mode])}, mean {np.mean(by_mode[mode]):.4f} s")
    if args.out is not None:
        shown = ["python", "-m", "localpbo_core.benchmarks.hybrid_compute"]
        doc = {
            "command": shlex.join(shown + (list(argv) if argv is not None else sys.argv[1:])),
            "machine": f"{os.cpu_count()} cores, {platform.system()} {platform.machine()}",
            "date": datetime.now(UTC).strftime("%Y-%m-%d"),
            "seconds": wall,
            "problem": args.problem,
            "problem_options": args.problem_options,
            "seeds": seeds,
            "algorithm": args.algorithm,
            "options": options,
            "iterations": n_iter,
            "turpbo_seconds_per_run": tr_all,
            "hybrid_seconds_per_run": hy_all,
            "ratio": hy_all / tr_all,
            "thirds": thirds,
            "local_asks": len(by_mode["local"]),
            "global_asks": len(by_mode["global"]),
            "probe_asks": len(by_mode["probe"]),
        }
        out = Path(args.out)
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_text(json.dumps(doc, indent=1, sort_keys=True) + "\n")
        print(out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
