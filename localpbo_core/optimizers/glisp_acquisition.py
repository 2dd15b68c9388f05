"""GLISp's acquisition in one pass over the samples, glis's value to the last bit.

GLISp (Bemporad & Piga 2021, Sec. 3.4; paper App. D.1) minimises, over the scaled box, at a
step with samples ``x_1 … x_N`` and RBF weights ``β``,

    a(x) = f̂(x) / ΔF − δ z(x),    f̂(x) = Σ_j β_j φ(ε‖x − x_j‖),    φ(r) = 1 / (1 + r²),

    z(x) = (1 − N/E) arctan(ẑ(x) · Σ_{j≠b} 1/‖x_b − x_j‖²) + (N/E) arctan(ẑ(x)),
    ẑ(x) = 1 / Σ_j (1 / ‖x − x_j‖²)

(inverse-distance exploration, ``z = 0`` at a sample; ``b`` the best sample, ``E`` glis's
``expected_max_evals``, ``ΔF`` the surrogate's range over the samples). glis evaluates it per
particle as two numpy/numba passes with temporaries (its RBF ``inverse_quadratic`` in numpy,
then the numba ``facquisition_pref_surrogate``, which recomputes the distances and the
exploration weights that only its unknown-constraint terms read).
:func:`surrogate_acquisition` computes ``a(x)`` in one compiled pass with each sum in the
order of the code it replaces (numpy's pairwise summation of a row for the RBF distance,
numba's sequential sums for the rest), so the value is glis's bit for bit
(``tests/optimizers/test_glisp_acquisition.py``); :func:`fast_acquisition` builds it from the
closure glis hands to its particle swarm, or declines when glis runs a variant it does not
reproduce (constraints, satisfaction, another acquisition or RBF).
"""

from __future__ import annotations

import inspect
from collections.abc import Callable
from typing import Any

import numpy as np
from numba import njit

#: numpy's pairwise summation: below this many terms a plain loop.
_PAIRWISE_UNROLL = 8
#: numpy's pairwise summation: up to this many terms one block of eight partial sums.
_PAIRWISE_BLOCK = 128
#: glis's "at a sample" distance threshold (squared distance).
_AT_SAMPLE = 1e-12


@njit(error_model="numpy")
def _pairwise_sum(a: np.ndarray, lo: int, n: int) -> float:  # pragma: no cover - compiled
    """numpy's ``pairwise_sum`` of ``a[lo:lo + n]`` (the order of ``np.sum`` along a row)."""
    if n < _PAIRWISE_UNROLL:
        res = 0.0
        for i in range(n):
            res += a[lo + i]
        return res
    if n <= _PAIRWISE_BLOCK:
        r0, r1, r2, r3 = a[lo], a[lo + 1], a[lo + 2], a[lo + 3]
        r4, r5, r6, r7 = a[lo + 4], a[lo + 5], a[lo + 6], a[lo + 7]
        i = 8
        whole = n - n % 8
        while i < whole:
            r0 += a[lo + i]
            r1 += a[lo + i + 1]
            r2 += a[lo + i + 2]
            r3 += a[lo + i + 3]
            r4 += a[lo + i + 4]
            r5 += a[lo + i + 5]
            r6 += a[lo + i + 6]
            r7 += a[lo + i + 7]
            i += 8
        res = ((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7))
        while i < n:
            res += a[lo + i]
            i += 1
        return res
    half = n // 2
    half -= half % 8
    return _pairwise_sum(a, lo, half) + _pairwise_sum(a, lo + half, n - half)


@njit(error_model="numpy")
def surrogate_acquisition(
    xs: np.ndarray,
    Xs: np.ndarray,
    W: np.ndarray,
    eps2: float,
    delta_E: float,
    dF: float,
    scale_delta: bool,
    N: float,
    maxevals: float,
    iw_ibest: float,
) -> float:  # pragma: no cover - compiled
    """GLISp's acquisition ``a(x)`` at ``xs`` (module docstring): glis's
    ``facquisition_pref_surrogate(xs, Xs, inverse_quadratic(Xs, xs, ε), W, ...)`` without
    unknown constraints or satisfaction, ``eps2 = ε ** 2`` as glis's RBF computes it."""
    n, dim = Xs.shape
    squares = np.empty(dim)
    fhat = 0.0
    inverse_sum = 0.0
    at_sample = False
    for j in range(n):
        sequential = 0.0
        for k in range(dim):
            diff = Xs[j, k] - xs[k]
            squares[k] = diff * diff
            sequential += squares[k]
        fhat += 1.0 / (1.0 + eps2 * _pairwise_sum(squares, 0, dim)) * W[j]
        if sequential < _AT_SAMPLE:
            at_sample = True
        inverse_sum += 1.0 / sequential
    if at_sample:
        dhat = 0.0
    else:
        aux = 1.0 / inverse_sum
        if not scale_delta:
            dhat = delta_E * np.arctan(aux)
        else:
            dhat = delta_E * (
                (1.0 - N / maxevals) * np.arctan(aux * iw_ibest) + N / maxevals * np.arctan(aux)
            )
    f = fhat / dF - dhat
    f += 0.0 * (1.0 - 1.0) + 0.0 * (1.0 - 1.0)  # glis's unknown-constraint terms, here 0
    return f


_CLOSURE_NAMES = frozenset({"Xs", "W", "delta_E", "dF", "delta_G", "delta_S", "N", "iw_ibest"})


def fast_acquisition(acquisition: Callable[[np.ndarray], float]) -> Callable[..., float] | None:
    """:func:`surrogate_acquisition` bound to the state of ``acquisition``, the closure glis
    2.0.2's ``GLISp.update`` gives its swarm; None where it would not give glis's values."""
    from glis.rbf import inverse_quadratic

    if acquisition.__closure__ is None:
        return None
    state = inspect.getclosurevars(acquisition).nonlocals
    glis: Any = state.get("self")
    if glis is None or not _CLOSURE_NAMES <= state.keys():
        return None
    if (
        glis.acquisition_method != "surrogate"
        or glis.rbf is not inverse_quadratic
        or glis.has_unknown_constraints
        or glis.has_satisfaction_fun
        or getattr(glis, "isLinConstrained", False)
        or getattr(glis, "isNLConstrained", False)
        or state["delta_G"] != 0.0
        or state["delta_S"] != 0.0
    ):
        return None
    Xs = np.ascontiguousarray(state["Xs"], dtype=np.float64)
    W = np.ascontiguousarray(state["W"], dtype=np.float64)
    if Xs.ndim != 2 or W.shape != (Xs.shape[0],):  # glis's product broadcasts otherwise
        return None
    epsil = glis.rbf_epsil * glis.theta
    eps2 = float(epsil**2)
    args = (
        eps2,
        float(state["delta_E"]),
        float(state["dF"]),
        bool(glis.scale_delta),
        float(state["N"]),
        float(glis.expected_max_evals),
        float(state["iw_ibest"]),
    )

    def objective(xs: np.ndarray) -> float:
        return surrogate_acquisition(xs, Xs, W, *args) + 0.0  # glis adds its penalty, 0.

    return objective
