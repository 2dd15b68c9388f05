"""Benchmark: why GLISp's first recalibration on Walker2d takes longer for some seeds.

Run ``python -m localpbo_core.benchmarks.glisp_recalibration``. With a warm start of 511
points, GLISp's first decision is glis's RBF recalibration (Bemporad & Piga 2021, Sec. 3.3;
:mod:`localpbo_core.optimizers.glisp`): for each of its 10 shape factors θ, one
leave-one-out fit per sample but the best, 10 × 510 linear programs of 510 points
(:mod:`localpbo_core.optimizers.glisp_lp`). The stored runs' first decisions differ by 5x
between seeds; this script measures what differs in their programs.

For each stored run ``policy_warm_start`` ``walker2d__glisp__seed<S>``: the run's plan is made
again as ``localpbo sweep`` makes it up to that recalibration, whose programs are not solved
(their weights are zeros) but kept: glis's RBF matrices for every θ, its comparisons and its
best sample; the replay stops there. The comparisons are checked against the stored run's
answers. Then, for each θ, every ``--stride``-th leave-one-out program is built as glis builds
it and solved by :func:`~localpbo_core.optimizers.glisp_lp.rbf_weights`, counting HiGHS's
simplex iterations. Prints per θ the mean iterations and seconds of those programs, and per
run the estimated recalibration (mean seconds × 510 per θ, summed) next to the stored first
decision. Seconds are this machine's under whatever else runs on it; iterations are not.

A later decision fits one program of all samples so far with the chosen θ. ``--later N``
(default 1021, the middle of the run) builds the program of step N from the stored
candidates (mapped back to the unit cube, so to rounding) and answers, and fits it from
scratch with every θ; printed next to the stored decisions' mean seconds around step N.

A script, not a test: it prints figures and asserts nothing about them.
"""

from __future__ import annotations

import argparse
import contextlib
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from localpbo_core.optimizers import glisp, glisp_lp

RUNS = Path(__file__).resolve().parents[2] / "docs" / "results" / "policy_warm_start" / "runs"


class _Stop(Exception):
    """Raised to end a replay once its first recalibration has been kept."""


@dataclass(frozen=True)
class Recalibration:
    """What glis's first recalibration fits: the RBF matrix of every shape factor (samples ×
    samples), the shape factors, the comparisons ``[better, worse]`` and ties, and the best
    sample."""

    matrices: tuple[np.ndarray, ...]
    thetas: np.ndarray
    prefs: np.ndarray
    ties: np.ndarray
    ibest: int
    sepvalue: float


Observer = Callable[[np.ndarray, int, np.ndarray, np.ndarray, int], None]
"""Sees each program of the recalibration: ``(M, n, prefs, ties, ibest)`` as glis passes it."""


def keep_first_recalibration(
    replay: Callable[[], object], observe: Observer | None = None
) -> Recalibration:
    """Call ``replay``, which makes a GLISp optimizer and drives it, and return what its first
    recalibration fits (module docstring). The recalibration's programs are not solved (zero
    weights, each seen by ``observe`` first); the replay ends by an exception at the first fit
    after them. Raises RuntimeError if the replay ends before."""
    kept: dict[str, Any] = {"calls": 0}
    real = glisp._fit_rbf_weights

    def record(
        glis: Any, M: np.ndarray, n: int, prefs: np.ndarray, ties: np.ndarray, ibest: int
    ) -> np.ndarray:
        if kept["calls"] == len(glis.thetas) * int(glis.iter):  # N + 1 samples, all but the best
            kept["owner"] = glis
            raise _Stop
        if observe is not None:
            observe(M, n, prefs, ties, ibest)
        kept["calls"] += 1
        return np.zeros(n)

    glisp._fit_rbf_weights = record
    try:
        with contextlib.suppress(_Stop):
            replay()
    finally:
        glisp._fit_rbf_weights = real
    if "owner" not in kept:
        raise RuntimeError("the replay ended before GLISp's first recalibration did")
    owner = kept["owner"]
    samples = int(owner.iter) + 1
    matrices = tuple(np.asarray(M) for M in owner.MM)
    if any(M.shape != (samples, samples) for M in matrices):
        raise RuntimeError(f"glis's RBF matrices are not {samples} x {samples}")
    return Recalibration(
        matrices=matrices,
        thetas=np.asarray(owner.thetas, dtype=float),
        prefs=np.asarray(owner.I, dtype=np.intp).reshape(-1, 2),
        ties=np.asarray(owner.Ieq, dtype=np.intp).reshape(-1, 2),
        ibest=int(owner.ibest),
        sepvalue=float(owner.sepvalue),
    )


def stored_plan(seed: int) -> Any:
    """The plan of ``walker2d__glisp__seed<seed>`` of ``policy_warm_start``."""
    from localpbo_core.experiments import load_spec

    run_id = f"walker2d__glisp__seed{seed}"
    return next(p for p in load_spec("policy_warm_start").runs() if p.run_id == run_id)


def replay_stored(plan: Any) -> Callable[[], object]:
    """``plan`` made again as ``localpbo sweep`` makes it."""
    from localpbo_core.sweep import execute_run

    return lambda: execute_run(plan)


def stored_comparisons(doc: dict[str, Any], count: int) -> set[tuple[int, int]]:
    """The decisive answers among a stored run's first ``count`` as ``(winner, loser)``."""
    pairs = set()
    for answer in doc["answers"][:count]:
        if answer["kind"] != "decisive":
            continue
        winner, first, second = answer["winner"], answer["first"], answer["second"]
        pairs.add((winner, second if winner == first else first))
    return pairs


def leave_one_out(
    recal: Recalibration, k: int, i: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
    """The program glis's ``rbf_calibrate`` fits for shape factor ``k`` without sample ``i``:
    the RBF matrix without row and column ``i``, the comparisons without ``i`` renumbered,
    and the best sample's new index."""
    M = recal.matrices[k]
    keep = np.delete(np.arange(M.shape[0]), i)

    def without(pairs: np.ndarray) -> np.ndarray:
        rest = pairs[~np.any(pairs == i, axis=1)]
        return rest - (rest > i)

    ibest = recal.ibest - 1 if recal.ibest > i else recal.ibest
    return M[np.ix_(keep, keep)], without(recal.prefs), without(recal.ties), ibest


@contextlib.contextmanager
def counted_iterations() -> Iterator[list[int]]:
    """Collect HiGHS's simplex iterations of every program solved in the block."""
    counts: list[int] = []
    base = glisp_lp.highs_core._Highs

    class Counting(base):  # type: ignore[misc, valid-type]
        def run(self) -> Any:
            status = super().run()
            counts.append(int(self.getInfo().simplex_iteration_count))
            return status

    glisp_lp.highs_core._Highs = Counting
    try:
        yield counts
    finally:
        glisp_lp.highs_core._Highs = base


def measure(recal: Recalibration, stride: int) -> list[tuple[float, float, float]]:
    """Per shape factor: θ, mean simplex iterations and mean seconds of every ``stride``-th
    leave-one-out program (the best sample is never left out, as in glis)."""
    out = []
    samples = recal.matrices[0].shape[0]
    left_out = [i for i in range(samples) if i != recal.ibest][::stride]
    for k, theta in enumerate(recal.thetas):
        seconds = []
        with counted_iterations() as counts:
            for i in left_out:
                M, prefs, ties, ibest = leave_one_out(recal, k, i)
                start = time.process_time()
                glisp_lp.rbf_weights(M, samples - 1, prefs, ties, ibest, recal.sepvalue)
                seconds.append(time.process_time() - start)
        out.append((float(theta), float(np.mean(counts)), float(np.mean(seconds))))
    return out


def later_program(
    doc: dict[str, Any], n: int, to_unit: Callable[[np.ndarray], np.ndarray]
) -> tuple[np.ndarray, np.ndarray, int]:
    """glis's scaled samples (``[-1, 1]^d``), comparisons ``[better, worse]`` and best sample
    of step ``n`` of a stored king-of-the-hill run (decisive answers only), its candidates
    mapped to the unit cube by ``to_unit``."""
    unit = np.array([to_unit(np.asarray(c["native"])) for c in doc["candidates"][:n]])
    pairs = stored_comparisons(doc, n - 1)
    prefs = np.array(sorted(pairs, key=max), dtype=np.intp).reshape(-1, 2)
    best = int(prefs[-1, 0]) if len(prefs) else 0
    return 2.0 * unit - 1.0, prefs, best


def stored_to_unit(plan: Any) -> Callable[[np.ndarray], np.ndarray]:
    """The unit-cube point of a stored Walker2d policy's weights (``plan``'s task)."""
    from localpbo_core.session import Session

    problem: Any = Session(plan.settings).problem
    return lambda native: np.asarray(problem.theta_from_weights(native).theta)


def later_fits(
    Xs: np.ndarray, prefs: np.ndarray, best: int, thetas: np.ndarray, sepvalue: float
) -> list[tuple[float, int, float]]:
    """Per θ: HiGHS's simplex iterations and CPU seconds of the fit of all of ``Xs`` from
    scratch (glis's inverse-quadratic RBF with ε = θ)."""
    distances = np.sum((Xs[:, None, :] - Xs[None, :, :]) ** 2, axis=-1)
    no_ties = np.zeros((0, 2), dtype=np.intp)
    out = []
    for theta in thetas:
        M = 1.0 / (1.0 + theta**2 * distances)
        with counted_iterations() as counts:
            start = time.process_time()
            glisp_lp.rbf_weights(M, len(Xs), prefs, no_ties, best, sepvalue)
            seconds = time.process_time() - start
        out.append((float(theta), sum(counts), seconds))
    return out


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m localpbo_core.benchmarks.glisp_recalibration",
        description="Simplex iterations and seconds of GLISp's first Walker2d recalibration.",
    )
    parser.add_argument(
        "--seeds", default="", help="comma-separated seeds; default every stored run"
    )
    parser.add_argument(
        "--stride", type=int, default=51, help="solve every STRIDE-th leave-one-out program"
    )
    parser.add_argument(
        "--later", type=int, default=1021, help="also fit step LATER's program; 0: not"
    )
    args = parser.parse_args(argv)
    from localpbo_core.sweep import read_run

    paths = sorted(RUNS.glob("walker2d__glisp__seed*.json.gz"))
    stored = {int(p.name.split("seed")[1].split(".")[0]): p for p in paths}
    seeds = [int(s) for s in args.seeds.split(",") if s] or sorted(stored)
    summary = []
    for seed in seeds:
        doc = read_run(stored[seed])
        plan = stored_plan(seed)
        recal = keep_first_recalibration(replay_stored(plan))
        same = stored_comparisons(doc, len(recal.prefs)) == {
            (int(a), int(b)) for a, b in recal.prefs
        }
        rows = measure(recal, args.stride)
        print(
            f"seed {seed}: {len(recal.prefs)} comparisons, {len(recal.ties)} ties, "
            f"as stored: {same}"
        )
        print(f"  {'theta':>7} {'iterations':>11} {'s/program':>10}")
        for theta, iterations, seconds in rows:
            print(f"  {theta:>7.3f} {iterations:>11.0f} {seconds:>10.3f}")
        per_theta = recal.matrices[0].shape[0] - 1
        estimate = sum(seconds for _, _, seconds in rows) * per_theta
        first = float(doc["records"][recal.matrices[0].shape[0]]["decision_seconds"])
        summary.append((seed, float(np.mean([r[1] for r in rows])), estimate, first))
        if args.later:
            Xs, prefs, best = later_program(doc, args.later, stored_to_unit(plan))
            fits = later_fits(Xs, prefs, best, recal.thetas, recal.sepvalue)
            around = doc["records"][args.later - 20 : args.later + 20]
            stored_later = float(np.mean([r["decision_seconds"] for r in around]))
            print(
                f"  step {args.later}, fitted from scratch (stored decisions there: "
                f"{stored_later:.2f} s)"
            )
            print(f"  {'theta':>7} {'iterations':>11} {'s/program':>10}")
            for theta, iterations, seconds in fits:
                print(f"  {theta:>7.3f} {iterations:>11} {seconds:>10.3f}")
    print(f"\n{'seed':>4} {'iterations':>11} {'estimate s':>11} {'stored s':>9} {'ratio':>6}")
    for seed, iterations, estimate, first in summary:
        print(
            f"{seed:>4} {iterations:>11.0f} {estimate:>11.0f} {first:>9.0f} "
            f"{first / estimate:>5.2f}x"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
