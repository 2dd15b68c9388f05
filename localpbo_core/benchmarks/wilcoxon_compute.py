"""The paired Wilcoxon test of the results page: :func:`localpbo_core.experiments.comparisons.
paired_wilcoxon` against scipy's ``wilcoxon`` on the same pairs, in the same process.

Ten seeds per group and algorithms that share candidates (the hybrid asks TuRPBO's until its
first local step) give tied or equal finals often; scipy then runs an exact permutation test
over all ``2**10`` sign flips with one Python call per flip. ``paired_wilcoxon`` computes the
same null distribution as one matrix product. ``--cases`` random sets of ``--pairs`` paired
finals (rounded to one decimal, so ties are common; one pair in three equal) are tested by
both; printed: the cases, how many took the permutation path, the seconds of each, the ratio
scipy / ours and whether every p-value came out equal bit for bit:

    python -m localpbo_core.benchmarks.wilcoxon_compute [--cases 200] [--pairs 10]
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Sequence

import numpy as np

from localpbo_core.experiments.comparisons import _paired_wilcoxon, takes_sign_flips


def cases(count: int, pairs: int, seed: int = 0) -> list[tuple[np.ndarray, np.ndarray]]:
    """``count`` paired samples of ``pairs`` values each, not all pairs equal."""
    rng = np.random.default_rng(seed)
    out: list[tuple[np.ndarray, np.ndarray]] = []
    while len(out) < count:
        x = np.round(rng.normal(size=pairs), 1)
        y = np.round(rng.normal(0.3, size=pairs), 1)
        equal = rng.random(pairs) < 1 / 3
        y[equal] = x[equal]
        if not np.all(x == y):
            out.append((x, y))
    return out


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m localpbo_core.benchmarks.wilcoxon_compute",
        description="Time paired_wilcoxon against scipy's wilcoxon on tied paired samples.",
    )
    parser.add_argument("--cases", type=int, default=200, help="paired samples (default 200)")
    parser.add_argument("--pairs", type=int, default=10, help="pairs per sample (default 10)")
    args = parser.parse_args(argv)
    if args.cases < 1:
        parser.error("--cases: must be at least 1")
    if not 1 <= args.pairs <= 50:
        parser.error("--pairs: must be 1 to 50")
    from scipy.stats import wilcoxon

    data = cases(args.cases, args.pairs)
    permutation = sum(takes_sign_flips(x - y) for x, y in data)
    start = time.perf_counter()
    reference = [float(wilcoxon(x, y).pvalue) for x, y in data]
    scipy_s = time.perf_counter() - start
    _paired_wilcoxon.cache_clear()
    start = time.perf_counter()
    ours = [_paired_wilcoxon(tuple(x.tolist()), tuple(y.tolist())) for x, y in data]
    ours_s = time.perf_counter() - start
    equal = reference == ours
    print(f"{'cases':>6} {'permutation':>11} {'scipy s':>8} {'ours s':>8} {'scipy/ours':>11} equal")
    print(
        f"{len(data):6d} {permutation:11d} {scipy_s:8.2f} {ours_s:8.3f} "
        f"{scipy_s / ours_s:11.1f} {equal}"
    )
    return 0 if equal else 1


if __name__ == "__main__":
    raise SystemExit(main())
