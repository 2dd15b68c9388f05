"""GLISp's particle swarm (``glisp_pso.pso``) against pyswarm's own ``pso``: the same best
point and value bit for bit, for swarms that stop early, that run to their last iteration
(the tries with more slabs) and inside whole GLISp runs."""

from __future__ import annotations

import numpy as np
import pyswarm
import pytest
from optim_helpers import drive

from localpbo_core.optimizers import glisp, glisp_pso
from localpbo_core.optimizers.glisp import GLISpOptimizer


def _objective(d: int, seed: int):
    centre = np.random.default_rng(seed).uniform(-0.5, 0.5, d)

    def f(x: np.ndarray) -> float:
        return float(np.sum((x - centre) ** 2) + 0.3 * np.sum(np.sin(7.0 * x)))

    return f


@pytest.mark.parametrize(
    ("d", "swarm", "maxiter", "minfunc", "minstep", "seed"),
    [
        (2, 20, 2000, 1e-4, 1e-8, 0),  # GLISp's settings, low d
        (102, 20, 2000, 1e-3, 1e-8, 1),  # GLISp's settings, Walker2d's d
        (8, 20, 100, 1e-9, 1e-8, 2),  # ends between the first and the second try
        (3, 7, 300, 0.0, -1.0, 3),  # never converges: every try, then all 300 iterations
        (4, 5, 64, 0.0, -1.0, 4),  # maxiter exactly the first try's slabs
        (5, 6, 10, 0.0, -1.0, 5),  # fewer iterations than the first try
    ],
)
def test_the_swarm_is_pyswarms_bit_for_bit(d, swarm, maxiter, minfunc, minstep, seed) -> None:
    f = _objective(d, seed)
    lb, ub = -np.ones(d), np.ones(d)
    reference = pyswarm.pso(
        f, lb, ub, swarmsize=swarm, maxiter=maxiter, minfunc=minfunc, minstep=minstep, seed=seed
    )
    x, fx = glisp_pso.pso(
        f, lb, ub, seed=seed, swarmsize=swarm, maxiter=maxiter, minfunc=minfunc, minstep=minstep
    )
    assert np.array_equal(x, reference.x)
    assert fx == reference.fun
    if minstep < 0:
        assert reference.nit == maxiter  # the case really ran to its last iteration


def test_a_swarm_that_reaches_the_first_tries_end_is_run_again(monkeypatch) -> None:
    """The loop that used all its slabs without converging is run again with more, from the
    start: the objective sees the first try's points again, then new ones."""
    f = _objective(3, 9)
    calls: list[np.ndarray] = []

    def counted(x: np.ndarray) -> float:
        calls.append(x.copy())
        return f(x)

    monkeypatch.setattr(glisp_pso, "FIRST_SLABS", 4)
    x, _ = glisp_pso.pso(counted, -np.ones(3), np.ones(3), seed=9, swarmsize=5, maxiter=40)
    reference = pyswarm.pso(f, -np.ones(3), np.ones(3), swarmsize=5, maxiter=40, seed=9)
    assert reference.nit > 4
    assert np.array_equal(x, reference.x)
    first_try = 5 + 4 * 5  # initial swarm and four iterations
    assert len(calls) > first_try
    again = calls[first_try : 2 * first_try]
    assert all(np.array_equal(a, b) for a, b in zip(calls[:first_try], again, strict=True))


def test_bad_bounds_are_refused() -> None:
    with pytest.raises(ValueError, match="ub > lb"):
        glisp_pso.pso(lambda x: 0.0, np.ones(2), np.ones(2), seed=0)


def test_whole_glisp_runs_are_the_same_with_pyswarms_swarm(monkeypatch) -> None:
    def run() -> list[np.ndarray]:
        opt = GLISpOptimizer(dim=5, seed=4, budget=40)
        return drive(opt, noise=0.05, rng=np.random.default_rng(2))

    ours = run()
    monkeypatch.setattr(glisp, "reproduces_installed_pyswarm", lambda: False)
    reference = run()
    assert all(np.array_equal(a, b) for a, b in zip(ours, reference, strict=True))
