"""GLISp's surrogate fit, the linear program of Bemporad & Piga (2021, Sec. 3.1), solved fast.

GLISp (paper Sec. 6, App. D.1 GLISp table) fits the weights β of its RBF surrogate
``f̂(x) = Σ_h β_h φ(x, x_h)`` to the comparisons by one linear program per step. With
``M_ih = φ(x_i, x_h)``, a strict preference "i better than j" (``[i, j]`` in ``I``) and a
tie (``[i, j]`` in ``Ieq``), separation σ, slacks ε ≥ 0 and β = β⁺ − β⁻ (β⁺, β⁻ ≥ 0)::

    minimise   1e-6 · Σ_h (β⁺_h + β⁻_h) + Σ_k c_k ε_k
    subject to (M_i − M_j)(β⁺ − β⁻) − ε_k ≤ −σ        for [i, j] in I
               ±(M_i − M_j)(β⁺ − β⁻) − ε_k ≤ σ        for [i, j] in Ieq (two rows)

with ``c_k = 10`` for comparisons that involve the current best and 1 otherwise. If HiGHS
finds no optimum, the weights' cost 1e-6 is raised to 1e-3 and the program solved again.
glis 2.0.2 writes the second row of a tie as ``−(M_i − M_j)(β⁺ + β⁻) − ε_k ≤ σ`` (both
weight blocks negated, not only the first); it is kept, so that ties are fitted as glis fits
them.

:func:`rbf_weights` is ``glis.solvers.GLISp.get_rbf_weights`` of glis 2.0.2 with the same
program, the same solver and the same answer to the last bit, only faster. glis hands the
program to ``scipy.optimize.linprog(method="highs")``, whose wrapper copies the matrix into
HiGHS element by element (1.2 million entries at d = 64 and 640 samples), and HiGHS's
presolve then searches the dense matrix and, nearly always, finds nothing to remove. Here
the same column-wise matrix goes to the same HiGHS build (scipy's bundled one, with the
options linprog sets) as numpy arrays, and presolve is left out whenever it cannot remove
anything. HiGHS's own simplex iterations stay as they are, so the gain is largest on small
programs (``python -m localpbo_core.benchmarks.glisp_lp`` prints it per size and over
whole stored runs).

Presolve changes the answer only if it reduces the program; when it finds nothing
("not reduced") HiGHS solves the original program, as with presolve off. Presolve runs
whenever the program has one of the structures it reduces here (:func:`presolve_can_reduce`:
a tie, a row without weight entries, a weight column of one sign, which early programs with
few comparisons, all against the best, have) and is left out otherwise.
``tests/optimizers/test_glisp_lp.py`` checks the answer bit for bit against glis's own fit,
and that presolve reduces nothing where it is left out, on the programs of whole GLISp runs;
``python -m localpbo_core.benchmarks.glisp_lp`` times both.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from scipy.optimize._highspy import _core as highs_core
from scipy.optimize._highspy._core import simplex_constants

#: The weights' L1 cost (glis's regularisation), and the one of its retry.
L1_COST = 1.0e-6
RETRY_L1_COST = 1.0e-3


def lp_matrix(M: np.ndarray, n: int, prefs: np.ndarray, ties: np.ndarray) -> np.ndarray:
    """The dense constraint matrix of the module docstring, entry for entry as glis builds
    it: one row per strict preference (``prefs``, glis's ``I``), then two rows per tie
    (``ties``, glis's ``Ieq``); columns β⁺ (n), β⁻ (n), one slack per comparison."""
    m, meq = len(prefs), len(ties)
    A = np.zeros((m + 2 * meq, 2 * n + m + meq))
    if m:
        strict = M[prefs[:, 0], 0:n] - M[prefs[:, 1], 0:n]
        A[:m, 0:n] = strict
        A[:m, n : 2 * n] = -strict
        A[np.arange(m), 2 * n + np.arange(m)] = -1.0
    if meq:
        tie = M[ties[:, 0], 0:n] - M[ties[:, 1], 0:n]
        rows = m + 2 * np.arange(meq)
        slack = 2 * n + m + np.arange(meq)
        A[rows, 0:n] = tie
        A[rows, n : 2 * n] = -tie
        A[rows + 1, 0:n] = -tie
        A[rows + 1, n : 2 * n] = -tie  # glis's second tie row (module docstring)
        A[rows, slack] = -1.0
        A[rows + 1, slack] = -1.0
    return A


def lp_costs(n: int, prefs: np.ndarray, ties: np.ndarray, ibest: int, l1: float) -> np.ndarray:
    """The cost vector of the module docstring (weights ``l1``, slacks 1 or 10)."""
    m, meq = len(prefs), len(ties)
    c = np.full(2 * n + m + meq, l1)
    c[2 * n :] = 1.0
    if m:
        c[2 * n + np.flatnonzero(np.any(prefs == ibest, axis=1))] = 10.0
    if meq:
        c[2 * n + m + np.flatnonzero(np.any(ties == ibest, axis=1))] = 10.0
    return c


def lp_rhs(m: int, meq: int, sepvalue: float) -> np.ndarray:
    """The right-hand sides: −σ for a strict preference, σ for both rows of a tie."""
    return np.concatenate([np.full(m, -sepvalue), np.full(2 * meq, sepvalue)])


def presolve_can_reduce(A: np.ndarray, n: int, meq: int) -> bool:
    """True if HiGHS's presolve may remove something from the program (module docstring):
    it has a tie, a row whose weight entries are all zero, or a weight column whose entries
    all have one sign (then β⁺_h or β⁻_h only tightens rows at a cost: presolve fixes it
    at 0)."""
    weights = A[:, 0:n]
    if meq > 0 or not weights.size:
        return True
    if np.any(~weights.any(axis=1)):
        return True
    return bool(np.any((weights >= 0).all(axis=0) | (weights <= 0).all(axis=0)))


def csc_parts(A: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``A``'s column starts, row indices and values in compressed sparse columns (int32
    indices): the arrays ``scipy.sparse.csc_array(A)`` holds, without its general
    conversion through coordinates."""
    columns = np.ascontiguousarray(A.T)
    nonzero = columns != 0
    starts = np.zeros(A.shape[1] + 1, dtype=np.int32)
    np.cumsum(nonzero.sum(axis=1), out=starts[1:])
    rows = np.nonzero(nonzero)[1].astype(np.int32)
    return starts, rows, columns[nonzero]


def solve_lp(
    c: np.ndarray, A: np.ndarray, b: np.ndarray, *, presolve: bool
) -> tuple[np.ndarray | None, Any]:
    """Minimise ``c·x`` subject to ``A x ≤ b``, ``x ≥ 0`` with scipy's HiGHS and the options
    ``linprog(method="highs")`` sets. Returns the optimum (None if HiGHS found none, as
    linprog's ``res.x``) and HiGHS's presolve status."""
    rows, cols = A.shape
    starts, indices, values = csc_parts(A)
    highs = highs_core._Highs()
    options = highs_core.HighsOptions()
    options.presolve = "on" if presolve else "off"
    options.log_to_console = False
    options.output_flag = False
    options.highs_debug_level = highs_core.HighsDebugLevel.kHighsDebugLevelNone
    options.simplex_strategy = simplex_constants.SimplexStrategy.kSimplexStrategyDual
    highs.passOptions(options)
    inf = highs_core.kHighsInf
    status = highs.passModel(
        cols,
        rows,
        len(values),
        int(highs_core.MatrixFormat.kColwise),
        int(highs_core.ObjSense.kMinimize),
        0.0,
        np.ascontiguousarray(c, dtype=np.float64),
        np.zeros(cols),
        np.full(cols, inf),
        np.full(rows, -inf),
        np.ascontiguousarray(b, dtype=np.float64),
        starts,
        indices,
        values,
        np.zeros(cols, dtype=np.int32),  # every column continuous
    )
    if status == highs_core.HighsStatus.kError:
        raise RuntimeError("glisp: HiGHS refused the surrogate's linear program")
    highs.run()
    presolved = highs.getModelPresolveStatus()
    if highs.getModelStatus() != highs_core.HighsModelStatus.kOptimal:
        return None, presolved
    return np.array(highs.getSolution().col_value), presolved


def rbf_weights(
    M: np.ndarray, n: int, prefs: Any, ties: Any, ibest: int, sepvalue: float
) -> np.ndarray:
    """The RBF weights β (length ``n``) of the module docstring's program, as
    ``glis.solvers.GLISp.get_rbf_weights(M, n, I, Ieq, ibest)`` returns them with
    ``I = prefs``, ``Ieq = ties`` (``k × 2`` sample indices ``[i, j]``, "i better than j",
    or empty) and ``self.sepvalue = sepvalue``."""
    strict = np.asarray(prefs, dtype=np.intp).reshape(-1, 2)
    equal = np.asarray(ties, dtype=np.intp).reshape(-1, 2)
    A = lp_matrix(M, n, strict, equal)
    b = lp_rhs(len(strict), len(equal), sepvalue)
    presolve = presolve_can_reduce(A, n, len(equal))
    for l1 in (L1_COST, RETRY_L1_COST):
        x, _ = solve_lp(lp_costs(n, strict, equal, ibest, l1), A, b, presolve=presolve)
        if x is not None:
            return x[0:n] - x[n : 2 * n]
    raise RuntimeError("glisp: the surrogate's linear program has no optimum")
