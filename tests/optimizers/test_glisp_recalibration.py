"""The recalibration benchmark's programs against glis's own: what
``benchmarks.glisp_recalibration`` keeps of a GLISp run's first recalibration, and the
leave-one-out programs it builds from that, equal the programs glis's ``rbf_calibrate`` hands
to the fit, call for call and bit for bit; the later program it builds from a run's
candidates and answers is glis's own samples, comparisons and best; a replay that never
recalibrates is an error."""

from __future__ import annotations

import numpy as np
import pytest
from optim_helpers import drive

from localpbo_core.benchmarks.glisp_recalibration import (
    counted_iterations,
    keep_first_recalibration,
    later_fits,
    later_program,
    leave_one_out,
)
from localpbo_core.optimizers import glisp_lp
from localpbo_core.optimizers.base import Outcome
from localpbo_core.optimizers.glisp import GLISpOptimizer


def _noisy_run(opt: GLISpOptimizer) -> None:
    direction = np.random.default_rng(7).standard_normal(opt.dim)
    drive(
        opt,
        lambda x: float(np.sin(3.0 * x @ direction) - np.sum((x - 0.4) ** 2)),
        0.2,
        np.random.default_rng(8),
    )


@pytest.mark.parametrize("initial_design", [2, 14])
def test_the_kept_programs_are_glis_own(initial_design: int) -> None:
    """glis recalibrates when its initial points are in (10 of them, or the 14 of a larger
    shared design, as a warm start makes it): 10 shape factors × every sample but the best."""
    seen: list[tuple[np.ndarray, int, np.ndarray, np.ndarray, int]] = []

    def run() -> None:
        opt = GLISpOptimizer(dim=4, seed=3, budget=40, initial_design=initial_design, pso_iters=30)
        _noisy_run(opt)

    recal = keep_first_recalibration(
        run, lambda M, n, prefs, ties, ibest: seen.append((M, n, prefs, ties, ibest))
    )
    samples = recal.matrices[0].shape[0]
    assert samples == max(10, initial_design)
    assert len(recal.prefs) + len(recal.ties) == samples - 1
    order = [(k, i) for k in range(len(recal.thetas)) for i in range(samples) if i != recal.ibest]
    assert len(seen) == len(order) == 10 * (samples - 1)
    for (k, i), (M, n, prefs, ties, ibest) in zip(order, seen, strict=True):
        ours = leave_one_out(recal, k, i)
        assert n == samples - 1
        assert np.array_equal(ours[0], M)
        assert np.array_equal(ours[1], np.asarray(prefs).reshape(-1, 2))
        assert np.array_equal(ours[2], np.asarray(ties).reshape(-1, 2))
        assert ours[3] == ibest


def test_the_iterations_are_counted_and_the_solver_restored() -> None:
    base = glisp_lp.highs_core._Highs
    rng = np.random.default_rng(0)
    X = rng.random((12, 3))
    M = 1.0 / (1.0 + np.sum((X[:, None] - X[None]) ** 2, axis=-1))
    pairs = np.array([[0, k] for k in range(1, 12)])
    with counted_iterations() as counts:
        glisp_lp.rbf_weights(M, 12, pairs, np.zeros((0, 2), dtype=np.intp), 0, 0.01)
    assert len(counts) == 1 and counts[0] > 0
    assert glisp_lp.highs_core._Highs is base


def test_a_replay_without_a_recalibration_is_an_error() -> None:
    with pytest.raises(RuntimeError, match="before GLISp's first recalibration"):
        keep_first_recalibration(lambda: None)


def test_the_later_program_is_glis_own_state() -> None:
    """A run written as a stored document (candidates as their unit points, answers as the
    sweep stores them) gives back glis's scaled samples, its comparisons and its best."""
    opt = GLISpOptimizer(dim=3, seed=4, budget=30, pso_iters=30)
    direction = np.random.default_rng(9).standard_normal(3)
    noise = np.random.default_rng(10)
    doc: dict[str, list[dict[str, object]]] = {"candidates": [], "answers": []}
    values: dict[int, float] = {}
    while not opt.done:
        ask = opt.ask()
        for c in ask.candidates:
            values[c.id] = float(np.sin(3.0 * c.theta @ direction)) + 0.2 * noise.standard_normal()
            doc["candidates"].append({"id": c.id, "native": list(c.theta)})
        outs = []
        for d in ask.duels:
            winner = d.first if values[d.first] >= values[d.second] else d.second
            loser = d.second if winner == d.first else d.first
            doc["answers"].append(
                {"first": d.first, "second": d.second, "kind": "decisive", "winner": winner}
            )
            outs.append(Outcome(winner, loser))
        opt.tell(outs)
    glis = opt.glis
    n = len(glis.I) + 1  # type: ignore[attr-defined]
    Xs, prefs, best = later_program(doc, n, np.asarray)
    scaled = (np.array(glis.X[:n]) - glis.d0) / glis.dd  # type: ignore[attr-defined]
    np.testing.assert_allclose(Xs, scaled, rtol=0, atol=1e-15)
    assert np.array_equal(prefs, np.array(glis.I))  # type: ignore[attr-defined]
    assert best == glis.ibest  # type: ignore[attr-defined]
    fits = later_fits(Xs, prefs, best, np.array([0.5, 2.0]), 0.01)
    assert [theta for theta, _, _ in fits] == [0.5, 2.0]
    assert all(iterations > 0 and seconds >= 0 for _, iterations, seconds in fits)
