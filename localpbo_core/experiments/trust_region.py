"""How TuRPBO's trust region behaved: side lengths and success rates over whole runs.

``python -m localpbo_core.experiments.trust_region SPEC [--problems P,..] [--algorithms A,..]
[--seeds S]`` runs the selected TuRPBO runs of an experiment spec in this process (the very
settings ``localpbo sweep`` stores, so the runs are the stored ones up to the machine's
rounding) and prints, per problem and algorithm label (means over the seeds):

* ``best``: the final best-seen true value;
* ``L>=0.8``, ``L=0.4``, ``L<=0.2``: the share of iterations whose candidates were proposed
  in a region of that side length (App. C.5, Alg. TurPBO: ``L_init = 0.8``, doubled after
  ``tau_succ = d`` consecutive successes up to 1.6, halved after ``tau_fail =
  ceil(max(4/q, d/q))`` consecutive failures, restarted below ``0.5^7``);
* ``won@0.8``, ``won@<=0.2``: the share of those iterations in which a candidate beat the
  region's center (a success), the quantity the counters add up;
* ``shrinks`` and ``restarts``: per run.

A success resets the failure counter, so under noisy duels a region halves only when
``tau_fail`` proposals in a row lose; chance wins (a noise-flipped duel, or a lucky proposal
against a weak center) keep it at its initial side. Unlike
:mod:`~localpbo_core.experiments.diagnose`, which reads stored duels, this re-runs the
optimizer, because stored runs do not record the region.
"""

from __future__ import annotations

import argparse
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from localpbo_core.experiments.spec import ExperimentSpec, PlannedRun, load_spec
from localpbo_core.optimizers.trust_region import TREvent, TRStep
from localpbo_core.settings import SettingError


@dataclass(frozen=True)
class RegionRun:
    """One TuRPBO run's trust-region history and final best-seen value."""

    problem: str
    algorithm: str
    seed: int
    best_seen: float
    steps: tuple[TRStep, ...]


def turpbo_runs(
    spec: ExperimentSpec,
    problems: Sequence[str] | None = None,
    algorithms: Sequence[str] | None = None,
    seeds: Sequence[int] | None = None,
) -> list[PlannedRun]:
    """The selected runs of ``spec``; every one must be a TuRPBO run.

    Raises:
        SettingError: a filter names a label or seed the spec does not have, or a selected
            run is not TuRPBO (field ``--algorithms``).
    """
    from localpbo_core.sweep import select_runs

    plans = select_runs(spec, problems, algorithms, None, seeds)
    others = sorted({p.algorithm_label for p in plans if p.settings.algorithm != "turpbo"})
    if others:
        raise SettingError("--algorithms", f"not TuRPBO runs: {', '.join(others)}")
    return plans


def run_region(plan: PlannedRun) -> RegionRun:
    """Run ``plan`` in this process and return its trust-region history."""
    from localpbo_core.loop import run_session
    from localpbo_core.optimizers.turpbo import TuRPBO
    from localpbo_core.session import Session

    session = Session(plan.settings)
    optimizer = session.optimizer
    if not isinstance(optimizer, TuRPBO):
        raise SettingError("--algorithms", f"{plan.algorithm_label} is not a TuRPBO run")
    trace = run_session(session)
    return RegionRun(
        problem=plan.problem_label,
        algorithm=plan.algorithm_label,
        seed=plan.seed,
        best_seen=float(trace.records[-1].best_seen),
        steps=tuple(optimizer.region_history),
    )


def _share(steps: Sequence[TRStep], keep: float, cmp: str) -> tuple[float, float]:
    """(share of ``steps`` whose length satisfies ``cmp keep``, success rate among them)."""
    if cmp == ">=":
        chosen = [s for s in steps if s.length >= keep]
    elif cmp == "<=":
        chosen = [s for s in steps if s.length <= keep]
    else:
        chosen = [s for s in steps if math.isclose(s.length, keep)]
    if not steps:
        return math.nan, math.nan
    won = float(np.mean([s.success for s in chosen])) if chosen else math.nan
    return len(chosen) / len(steps), won


def table(runs: Sequence[RegionRun]) -> list[str]:
    """The printed table (module docstring), one row per problem and algorithm label."""
    pw = max([len("problem"), *(len(r.problem) for r in runs)]) + 2
    aw = max([len("algorithm"), *(len(r.algorithm) for r in runs)]) + 2
    head = (
        f"{'problem':<{pw}}{'algorithm':<{aw}}{'seeds':>6}{'best':>10}{'L>=0.8':>8}"
        f"{'L=0.4':>7}{'L<=0.2':>8}{'won@0.8':>9}{'won@<=0.2':>11}{'shrinks':>9}{'restarts':>10}"
    )
    lines = [head]
    for problem, algorithm in sorted({(r.problem, r.algorithm) for r in runs}):
        mine = [r for r in runs if (r.problem, r.algorithm) == (problem, algorithm)]

        def mean(values: Sequence[float]) -> float:
            finite = [v for v in values if not math.isnan(v)]
            return float(np.mean(finite)) if finite else math.nan

        wide = [_share(r.steps, 0.8, ">=") for r in mine]
        mid = [_share(r.steps, 0.4, "==") for r in mine]
        narrow = [_share(r.steps, 0.2, "<=") for r in mine]
        shrinks = [sum(s.event is TREvent.SHRINK for s in r.steps) for r in mine]
        restarts = [sum(s.event is TREvent.RESTART for s in r.steps) for r in mine]
        lines.append(
            f"{problem:<{pw}}{algorithm:<{aw}}{len(mine):>6}"
            f"{mean([r.best_seen for r in mine]):>10.4g}"
            f"{mean([w[0] for w in wide]):>8.2f}{mean([m[0] for m in mid]):>7.2f}"
            f"{mean([n[0] for n in narrow]):>8.2f}"
            f"{mean([w[1] for w in wide]):>9.2f}{mean([n[1] for n in narrow]):>11.2f}"
            f"{np.mean(shrinks):>9.1f}{np.mean(restarts):>10.1f}"
        )
    return lines


def main(argv: Sequence[str] | None = None) -> int:
    """Run the selected TuRPBO runs of a spec and print the trust-region table."""
    from tqdm import tqdm

    from localpbo_core.arguments import parse_seeds

    ap = argparse.ArgumentParser(prog="python -m localpbo_core.experiments.trust_region")
    ap.add_argument("spec", help="spec file or bundled spec name")
    ap.add_argument("--problems", default="", help="problem labels, comma-separated")
    ap.add_argument("--algorithms", default="", help="algorithm labels, comma-separated")
    ap.add_argument("--seeds", default=None, help="seeds or ranges, e.g. 0-4")
    args = ap.parse_args(argv)

    def labels(text: str) -> list[str] | None:
        return [t for t in text.split(",") if t] or None

    try:
        plans = turpbo_runs(
            load_spec(args.spec),
            labels(args.problems),
            labels(args.algorithms),
            None if args.seeds is None else parse_seeds(args.seeds),
        )
    except SettingError as exc:
        ap.exit(2, f"{ap.prog}: error: {exc.field}: {exc.reason}\n")
    runs = [run_region(plan) for plan in tqdm(plans, unit="run", dynamic_ncols=True)]
    print("\n".join(table(runs)))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
