"""GLISp's acquisition in one pass (``glisp_acquisition``) against glis's own: the same value
bit for bit on random states (dimensions on both sides of numpy's pairwise blocks, points
at a sample, both exploration forms), from the closure glis hands its swarm, the variants it
declines, and whole GLISp runs the same with glis's path."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from optim_helpers import drive

from localpbo_core.optimizers import glisp, glisp_acquisition
from localpbo_core.optimizers.glisp import GLISpOptimizer, _glis_solvers
from localpbo_core.optimizers.glisp_acquisition import fast_acquisition, surrogate_acquisition


def _glis_value(xs, Xs, W, epsil, delta_E, dF, scale_delta, N, E, iw_best) -> float:
    """glis 2.0.2's acquisition as its ``GLISp.update`` evaluates it (no constraints)."""
    from glis.rbf import inverse_quadratic

    n = len(Xs)
    solvers: Any = _glis_solvers()
    value = solvers.facquisition_pref_surrogate(
        xs.T, Xs, inverse_quadratic(Xs, xs.T, epsil), W, delta_E, dF, 0.0, 0.0, scale_delta,
        N, E, iw_best, False, False, np.ones(n, bool), np.ones(n, bool),
    )  # fmt: skip
    return value + 0.0


@pytest.mark.parametrize("d", [1, 2, 7, 8, 9, 33, 102, 128, 129, 200, 300])
def test_the_value_is_glis_bit_for_bit(d: int) -> None:
    rng = np.random.default_rng(d)
    for trial in range(12):
        n = int(rng.integers(2, 300))
        Xs = rng.random((n, d)) * 2.0 - 1.0
        W = rng.standard_normal(n) * 10.0 ** rng.uniform(-3, 2)
        epsil = np.float64((0.1, 0.5, 1.0, 3.3)[trial % 4])
        dF, N, E = max(float(rng.random() * 5.0), 1e-4), float(n - 1), 100.0
        iw_best = float(sum(1.0 / np.sum((Xs[1:] - Xs[0]) ** 2, axis=-1)))
        scale_delta = bool(trial % 3)
        for xs in (rng.random(d) * 2.0 - 1.0, Xs[int(rng.integers(n))].copy()):
            ours = surrogate_acquisition(
                xs, Xs, W, float(epsil**2), 0.5, dF, scale_delta, N, E, iw_best
            )
            reference = _glis_value(xs, Xs, W, epsil, 0.5, dF, scale_delta, N, E, iw_best)
            assert ours + 0.0 == reference


def _captured_acquisition():
    """The acquisition closure glis hands its swarm at the third active step of a GLISp run,
    with the glis instance."""
    opt = GLISpOptimizer(dim=4, seed=1, budget=30, n_initial_random=6)
    captured: list[Any] = []
    real = glisp_acquisition.fast_acquisition

    def capture(acquisition):
        captured.append(acquisition)
        return real(acquisition)

    glisp_acquisition.fast_acquisition = capture
    try:
        drive(opt)
    finally:
        glisp_acquisition.fast_acquisition = real
    return captured[2], opt.glis


def test_the_closure_glis_gives_its_swarm_is_reproduced() -> None:
    acquisition, _ = _captured_acquisition()
    fast = fast_acquisition(acquisition)
    assert fast is not None
    rng = np.random.default_rng(0)
    for _ in range(200):
        xs = rng.random(4) * 2.0 - 1.0
        assert fast(xs) == acquisition(xs)


@pytest.mark.parametrize(
    "change",
    [
        {"acquisition_method": "prob_improvement"},
        {"has_unknown_constraints": True},
        {"has_satisfaction_fun": True},
    ],
)
def test_variants_it_does_not_reproduce_are_declined(change) -> None:
    acquisition, glis = _captured_acquisition()
    for key, value in change.items():
        setattr(glis, key, value)
    assert fast_acquisition(acquisition) is None


def test_other_callables_are_declined() -> None:
    assert fast_acquisition(lambda xs: 0.0) is None

    def no_glis(xs):
        return float(np.sum(xs))

    assert fast_acquisition(no_glis) is None


def test_whole_glisp_runs_are_the_same_as_with_glis_own_path(monkeypatch) -> None:
    """A GLISp run with glis's acquisition under pyswarm's own ``pso`` chooses the same
    candidates as one with the one-pass acquisition and the lazy swarm."""

    def run() -> list[np.ndarray]:
        opt = GLISpOptimizer(dim=9, seed=3, budget=60)
        return drive(opt, noise=0.05, rng=np.random.default_rng(5))

    ours = run()
    monkeypatch.setattr(glisp_acquisition, "fast_acquisition", lambda acquisition: None)
    monkeypatch.setattr(glisp, "reproduces_installed_pyswarm", lambda: False)
    reference = run()
    assert all(np.array_equal(a, b) for a, b in zip(ours, reference, strict=True))
