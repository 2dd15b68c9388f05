"""What the duels of stored runs looked like: a diagnosis of why an algorithm fell short.

``python -m localpbo_core.experiments.diagnose RESULTS... [--problems P,..] [--algorithms A,..]``
reads stored runs (``localpbo sweep`` or ``localpbo bench --out`` files) and prints, per
problem and algorithm (means over the seeds found):

* ``flipped``: the share of decisive duels won by the candidate whose true value is lower.
  With the oracle's noise (paper Sec. 6, App. D.1: σ = ``noise_fraction`` times the problem's
  value range, on each of the two values compared) a duel between values ``Δ`` apart is
  flipped with probability ``Φ(-|Δ| / (σ√2))``: about one half when ``|Δ| ≪ σ``.
* ``|Δ|/σ``: the median true difference of the dueled pairs in units of that σ.
* ``proposals``: the mean true value of the points the algorithm proposed (its initial
  design excluded), beside ``random``: the mean over the problem's uniform points (the
  Sobol runs' points when they are among the inputs, else 1024 uniform points, seed 0).
* ``at bound``: the share of proposed coordinates within 1 % of the box's edge (a uniform
  point has 2 %).
* ``won``: the share of duels won by the newer point (the proposal against what it was
  compared with); ``better``: the share of those duels in which the newer point's true value
  is the higher one (what ``won`` would be without noise); ``step``: the median distance, in
  the unit cube, between the newer point and the point it was compared with; and
  ``lost streak``: the longest run of consecutive such duels lost, the quantity TuRPBO's
  failure tolerance counts (App. C.5: it halves the trust region after
  ``τ_fail = max(4/q, d/q)`` consecutive failures).

It uses only the stored candidates, their true values and the answers: nothing is re-run.
"""

from __future__ import annotations

import argparse
import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from localpbo_core.problems.registry import make_problem
from localpbo_core.run_documents import run_files

EDGE = 0.01
"""A coordinate is "at a bound" within this fraction of its box side."""


@dataclass(frozen=True)
class RunDiagnosis:
    """The duel statistics of one stored run (see module docstring)."""

    problem: str
    algorithm: str
    seed: int
    dim: int
    duels: int
    flipped: float
    median_gap_sigma: float
    proposals_mean: float
    at_bound: float
    newer_won: float
    newer_better: float
    median_step: float
    longest_lost_streak: int


def diagnose_run(doc: dict[str, Any], problem: Any | None = None) -> RunDiagnosis:
    """Diagnose one stored run (the document :func:`localpbo_core.sweep.read_run` returns).

    ``problem`` is the run's problem (made from its settings when omitted); it gives the
    value range (the noise scale) and the box of the native parameters.
    """
    s = doc["settings"]
    meta = doc.get("run") or {}
    if problem is None:
        problem = make_problem(s["problem"], **(s.get("problem_options") or {}))
    sigma = float(s["noise_fraction"]) * float(problem.value_range)
    dim = int(problem.dim)
    lo = np.asarray(problem.to_native(np.zeros(dim)), dtype=np.float64)
    hi = np.asarray(problem.to_native(np.ones(dim)), dtype=np.float64)
    value = {int(c["id"]): float(c["value"]) for c in doc["candidates"]}
    native = {int(c["id"]): np.asarray(c["native"], dtype=np.float64) for c in doc["candidates"]}
    side = np.where(hi > lo, hi - lo, 1.0)
    flips = 0
    gaps = []
    won = []
    better = []
    steps = []
    for a in doc["answers"]:
        if a.get("kind", "decisive") != "decisive":  # older files hold decisive duels only
            continue
        first, second, winner = int(a["first"]), int(a["second"]), int(a["winner"])
        loser = second if winner == first else first
        newer, older = max(first, second), min(first, second)
        flips += value[winner] < value[loser]
        gaps.append(abs(value[first] - value[second]))
        won.append(winner == newer)
        better.append(value[newer] > value[older])
        steps.append(float(np.linalg.norm((native[newer] - native[older]) / side)))
    streak = longest = 0
    for w in won:
        streak = 0 if w else streak + 1
        longest = max(longest, streak)
    proposed = [i for i in sorted(value) if i >= int(s["initial_design"])]
    x = np.array([native[i] for i in proposed]).reshape(len(proposed), dim)
    near = (np.abs(x - lo) <= EDGE * side) | (np.abs(hi - x) <= EDGE * side)
    n = len(won)
    return RunDiagnosis(
        problem=str(meta.get("problem_label", s["problem"])),
        algorithm=str(meta.get("algorithm_label", s["algorithm"])),
        seed=int(s["seed"]),
        dim=dim,
        duels=n,
        flipped=flips / n if n else math.nan,
        median_gap_sigma=float(np.median(gaps)) / sigma if gaps and sigma > 0 else math.nan,
        proposals_mean=float(np.mean([value[i] for i in proposed])) if proposed else math.nan,
        at_bound=float(near.mean()) if near.size else math.nan,
        newer_won=float(np.mean(won)) if won else math.nan,
        newer_better=float(np.mean(better)) if better else math.nan,
        median_step=float(np.median(steps)) if steps else math.nan,
        longest_lost_streak=longest,
    )


def uniform_mean(problem: Any, n: int = 1024, seed: int = 0) -> float:
    """Mean true value of ``n`` uniform points of ``problem`` (the "random" reference)."""
    rng = np.random.default_rng(seed)
    return float(np.mean([problem.true_value(rng.random(problem.dim)) for _ in range(n)]))


def diagnose(
    paths: Iterable[str | Path],
    problems: Sequence[str] = (),
    algorithms: Sequence[str] = (),
) -> list[RunDiagnosis]:
    """Diagnose every stored run under ``paths`` (filtered by problem and algorithm label)."""
    from localpbo_core.sweep import read_run

    made: dict[tuple[str, str], Any] = {}
    out = []
    for path in run_files(paths):
        doc = read_run(path)
        s = doc["settings"]
        meta = doc.get("run") or {}
        label = str(meta.get("problem_label", s["problem"]))
        algo = str(meta.get("algorithm_label", s["algorithm"]))
        if (problems and label not in problems) or (algorithms and algo not in algorithms):
            continue
        key = (s["problem"], repr(sorted((s.get("problem_options") or {}).items())))
        if key not in made:
            made[key] = make_problem(s["problem"], **(s.get("problem_options") or {}))
        out.append(diagnose_run(doc, made[key]))
    return out


def random_references(
    paths: Iterable[str | Path], diagnoses: Sequence[RunDiagnosis]
) -> dict[str, float]:
    """Per problem label: the mean true value of a uniform point, from the Sobol runs among
    the diagnoses, else from :func:`uniform_mean` of the problem of a run stored under
    ``paths``."""
    from localpbo_core.sweep import read_run

    sobol: dict[str, list[float]] = {}
    for d in diagnoses:
        if d.algorithm == "sobol":
            sobol.setdefault(d.problem, []).append(d.proposals_mean)
    out = {p: float(np.mean(v)) for p, v in sobol.items()}
    missing = {d.problem for d in diagnoses} - set(out)
    for path in run_files(paths):
        if not missing:
            break
        doc = read_run(path)
        s = doc["settings"]
        label = str((doc.get("run") or {}).get("problem_label", s["problem"]))
        if label in missing:
            out[label] = uniform_mean(
                make_problem(s["problem"], **(s.get("problem_options") or {}))
            )
            missing.discard(label)
    return out


def table(diagnoses: Sequence[RunDiagnosis], random_means: dict[str, float]) -> list[str]:
    """One line per problem and algorithm: means over the seeds."""
    width = max([len("algorithm"), *(len(d.algorithm) for d in diagnoses)]) + 1
    header = (
        f"{'problem':<18}{'algorithm':<{width}}{'seeds':>6}{'flipped':>9}{'|Δ|/σ':>8}"
        f"{'proposals':>12}{'random':>12}{'at bound':>10}{'won':>7}{'better':>8}{'step':>8}"
        f"{'lost streak':>13}"
    )
    lines = [header]
    groups: dict[tuple[str, str], list[RunDiagnosis]] = {}
    for d in diagnoses:
        groups.setdefault((d.problem, d.algorithm), []).append(d)
    for (problem, algorithm), ds in sorted(groups.items()):
        streaks = [d.longest_lost_streak for d in ds]
        lines.append(
            f"{problem:<18}{algorithm:<{width}}{len(ds):>6}"
            f"{np.mean([d.flipped for d in ds]):>9.2f}"
            f"{np.mean([d.median_gap_sigma for d in ds]):>8.2f}"
            f"{np.mean([d.proposals_mean for d in ds]):>12.4g}"
            f"{random_means.get(problem, math.nan):>12.4g}"
            f"{np.mean([d.at_bound for d in ds]):>10.3f}"
            f"{np.mean([d.newer_won for d in ds]):>7.2f}"
            f"{np.mean([d.newer_better for d in ds]):>8.2f}"
            f"{np.mean([d.median_step for d in ds]):>8.3f}"
            f"{f'{min(streaks)}-{max(streaks)}':>13}"
        )
    return lines


def main(argv: Sequence[str] | None = None) -> int:
    """Print the diagnosis table of the stored runs given on the command line."""
    ap = argparse.ArgumentParser(prog="python -m localpbo_core.experiments.diagnose")
    ap.add_argument("results", nargs="+", help="result folders or run files")
    ap.add_argument("--problems", default="", help="problem labels, comma-separated")
    ap.add_argument("--algorithms", default="", help="algorithm labels, comma-separated")
    args = ap.parse_args(argv)
    problems = [p for p in args.problems.split(",") if p]
    algorithms = [a for a in args.algorithms.split(",") if a]
    ds = diagnose(args.results, problems, algorithms)
    print("\n".join(table(ds, random_references(args.results, ds))))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
