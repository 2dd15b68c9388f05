"""GLISp's surrogate fit (``glisp_lp.rbf_weights``) against glis's own ``get_rbf_weights``:
the same weights bit for bit on hand-made programs (ties, duplicate samples, early programs)
and the same candidates over whole GLISp runs; presolve left out only where it reduces
nothing; the retry and the failure of the program."""

from __future__ import annotations

import copy
from types import SimpleNamespace

import numpy as np
import pytest
from optim_helpers import drive
from scipy.sparse import csc_array

from localpbo_core.benchmarks.glisp_lp import glisp_program
from localpbo_core.optimizers import glisp_lp
from localpbo_core.optimizers.glisp import GLISpOptimizer, _glis_solvers
from localpbo_core.optimizers.glisp_lp import RETRY_L1_COST, rbf_weights

SEPARATION = 0.01
NO_TIES = np.zeros((0, 2), dtype=np.intp)


def glis_fit(M, n, prefs, ties, ibest, sepvalue=SEPARATION) -> np.ndarray:
    """glis 2.0.2's own fit (``scipy.optimize.linprog``), the reference."""
    owner = SimpleNamespace(sepvalue=sepvalue)
    fit = _glis_solvers().GLISp.get_rbf_weights
    return fit(owner, M, n, np.array(prefs), np.array(ties), ibest)


@pytest.mark.parametrize(("d", "n", "seed"), [(2, 5, 0), (6, 40, 1), (16, 120, 2), (32, 240, 3)])
def test_the_weights_equal_glis_bit_for_bit(d, n, seed) -> None:
    M, pairs, best = glisp_program(d, n, seed)
    assert np.array_equal(
        rbf_weights(M, n, pairs, NO_TIES, best, SEPARATION), glis_fit(M, n, pairs, NO_TIES, best)
    )
    # ties (glis's equality rows, presolve on), some of them against the best
    ties, strict = pairs[::4], np.delete(pairs, np.s_[::4], axis=0)
    assert np.array_equal(
        rbf_weights(M, n, strict, ties, best, 0.05), glis_fit(M, n, strict, ties, best, 0.05)
    )
    # a program of fewer samples than M has rows (a recalibration's leave-one-out)
    k = n // 2
    sub = pairs[(pairs < k).all(axis=1)]
    sub_best = int(sub[0, 0]) if len(sub) else 0
    assert np.array_equal(
        rbf_weights(M, k, sub, NO_TIES, sub_best, SEPARATION),
        glis_fit(M, k, sub, NO_TIES, sub_best),
    )


def test_the_sparse_columns_are_scipys() -> None:
    """:func:`csc_parts` gives the arrays of ``scipy.sparse.csc_array`` (zeros of either sign
    left out, rows ascending), the matrix HiGHS gets through linprog."""
    M, pairs, _ = glisp_program(6, 30, 7)
    A = glisp_lp.lp_matrix(M, 30, pairs[1:], pairs[:3])
    A[2, 5], A[4, 40] = -0.0, 1e-300  # a negative zero and a tiny entry
    starts, rows, values = glisp_lp.csc_parts(A)
    reference = csc_array(A)
    assert starts.dtype == rows.dtype == np.int32
    np.testing.assert_array_equal(starts, reference.indptr)
    np.testing.assert_array_equal(rows, reference.indices)
    np.testing.assert_array_equal(values, reference.data)


def test_duplicate_samples_and_programs_against_the_best_equal_glis() -> None:
    M, pairs, best = glisp_program(8, 30, 4)
    # two equal samples: their comparison's row has no weight entries
    twin = M.copy()
    twin[7], twin[:, 7] = twin[3], twin[:, 3]
    twin[7, 7] = 1.0
    dup = np.vstack([pairs, [[3, 7]]])
    assert glisp_lp.presolve_can_reduce(glisp_lp.lp_matrix(twin, 30, dup, NO_TIES), 30, 0)
    assert np.array_equal(
        rbf_weights(twin, 30, dup, NO_TIES, best, SEPARATION),
        glis_fit(twin, 30, dup, NO_TIES, best),
    )
    # the first programs of a run: every comparison against one best sample
    early = np.array([[0, k] for k in range(1, 6)])
    assert glisp_lp.presolve_can_reduce(glisp_lp.lp_matrix(M, 6, early, NO_TIES), 6, 0)
    assert np.array_equal(
        rbf_weights(M, 6, early, NO_TIES, 0, SEPARATION), glis_fit(M, 6, early, NO_TIES, 0)
    )
    # no comparison at all
    empty = np.zeros((0, 2), dtype=np.intp)
    assert np.array_equal(
        rbf_weights(M, 4, empty, NO_TIES, 0, SEPARATION), glis_fit(M, 4, [], [], 0)
    )


def _noisy_run(opt: GLISpOptimizer) -> list[np.ndarray]:
    rng = np.random.default_rng(11)
    direction = np.random.default_rng(12).standard_normal(opt.dim)
    return drive(
        opt, lambda x: float(np.sin(3.0 * x @ direction) - np.sum((x - 0.4) ** 2)), 0.2, rng
    )


def test_a_whole_run_equals_the_run_with_glis_fit() -> None:
    """The candidates of a noisy GLISp run through two recalibrations (E = 100 puts them at
    10 and 32 samples) equal those of the same run with glis's own fit."""
    dim, budget, seed = 12, 36, 5
    ours = GLISpOptimizer(dim=dim, seed=seed, budget=budget, pso_iters=30)
    theirs = GLISpOptimizer(dim=dim, seed=seed, budget=budget, pso_iters=30)
    del theirs.glis.get_rbf_weights  # back to glis's method: linprog
    a, b = _noisy_run(ours), _noisy_run(theirs)
    assert len(a) == budget
    np.testing.assert_array_equal(np.stack(a), np.stack(b))


def test_presolve_is_left_out_only_where_it_reduces_nothing(monkeypatch) -> None:
    """Over every program of a GLISp run: where presolve is left out, HiGHS with presolve
    finds nothing to reduce and gives the same solution; where it runs, some programs are
    reduced (the early ones)."""
    real = glisp_lp.solve_lp
    seen = {True: 0, False: 0}
    reduced = 0

    def checked(c, A, b, *, presolve):
        nonlocal reduced
        x, status = real(c, A, b, presolve=presolve)
        seen[presolve] += 1
        if presolve:
            reduced += status != glisp_lp.highs_core.HighsPresolveStatus.kNotReduced
        else:
            x_on, status_on = real(c, A, b, presolve=True)
            assert status_on == glisp_lp.highs_core.HighsPresolveStatus.kNotReduced
            assert np.array_equal(x, x_on)
        return x, status

    monkeypatch.setattr(glisp_lp, "solve_lp", checked)
    _noisy_run(GLISpOptimizer(dim=6, seed=3, budget=40, pso_iters=30))
    assert seen[False] > 10 * seen[True] > 0 and reduced > 0


def test_the_retry_raises_the_weights_cost_and_a_failure_is_an_error(monkeypatch) -> None:
    M, pairs, best = glisp_program(4, 12, 6)
    real = glisp_lp.solve_lp
    costs: list[float] = []

    def first_fails(c, A, b, *, presolve):
        costs.append(float(c[0]))
        return (None, None) if len(costs) == 1 else real(c, A, b, presolve=presolve)

    monkeypatch.setattr(glisp_lp, "solve_lp", first_fails)
    weights = rbf_weights(M, 12, pairs, NO_TIES, best, SEPARATION)
    assert costs == [glisp_lp.L1_COST, RETRY_L1_COST] and weights.shape == (12,)
    monkeypatch.setattr(glisp_lp, "solve_lp", lambda c, A, b, *, presolve: (None, None))
    with pytest.raises(RuntimeError, match="no optimum"):
        rbf_weights(M, 12, pairs, NO_TIES, best, SEPARATION)


def test_a_copied_optimizer_fits_with_its_own_glis() -> None:
    """A deep copy (a session's speculative twin) fits the copy's samples, not the original's."""
    opt = GLISpOptimizer(dim=3, seed=0, budget=14)
    twin = copy.deepcopy(opt)
    assert twin.glis.get_rbf_weights.__self__ is twin.glis
    np.testing.assert_array_equal(np.stack(drive(opt)), np.stack(drive(twin)))
