"""GLISp's particle swarm, pyswarm's ``pso`` without the random numbers it never reads.

GLISp (paper Sec. 6, App. D.1 GLISp table) picks each next point by a particle swarm over its
acquisition (``glis`` calls ``pyswarm.pso`` with ``S`` particles in ``D`` dimensions and at most
``T = 2000`` iterations). pyswarm 1.1.2's ``pso`` draws from ``numpy.random.default_rng(seed)``,
in this order, the initial positions ``x0`` (``S × D`` uniform on the box), the initial
velocities ``v0`` (``S × D``), and the random factors of every iteration ``r_p`` and ``r_g``
(``T × S × D`` each), then runs its compiled loop: iteration ``t`` moves particle ``s`` by

    v ← ω v + φ_p r_p[t, s] ⊙ (p_s − x_s) + φ_g r_g[t, s] ⊙ (g − x_s),    x_s ← x_s + v,

and the loop ends after ``T`` iterations or when the best point's step or value change falls
below ``minstep`` or ``minfunc``. GLISp's swarms end after a few dozen iterations, so nearly
all of the ``2 T S D`` factors (65 MB at ``D = 102``, drawn and copied to Fortran order at
every step of a run) are never read.

:func:`pso` draws ``x0``, ``v0`` and only the first ``m`` slabs of ``r_p`` and ``r_g`` (the
generator is advanced past the unread slabs, PCG64's ``advance``: one 64-bit draw per double)
and runs pyswarm's own compiled loop on them. A loop that stops before ``m`` iterations read
only what it was given, the same numbers as pyswarm's; one that used all ``m`` slabs
(status "maximum iterations") is run again from the start with four times as many, up to
``T``. The result is pyswarm's bit for bit (``tests/optimizers/test_glisp_pso.py`` checks
against ``pyswarm.pso``); ``python -m localpbo_core.benchmarks.glisp_pso`` gives the time.
"""

from __future__ import annotations

from collections.abc import Callable
from importlib.metadata import version

import numpy as np

#: The pyswarm release whose ``pso`` this module reproduces (its draws, order and loop).
PYSWARM_VERSION = "1.1.2"
#: Iterations' random factors drawn before the first try of the loop.
FIRST_SLABS = 64
#: pyswarm's status code for "maximum iterations reached".
MAXITER_STATUS = 0
#: pyswarm's marker of an infeasible particle; GLISp's acquisition has no constraints.
INFEASIBLE = 1.0e300


def reproduces_installed_pyswarm() -> bool:
    """Whether the installed pyswarm is the release :func:`pso` reproduces."""
    return version("pyswarm") == PYSWARM_VERSION


def _factors(seed: int, skip: int, count: int) -> np.ndarray:
    """``count`` doubles of ``default_rng(seed)``'s stream after its first ``skip``."""
    bits = np.random.PCG64(np.random.SeedSequence(seed))
    bits.advance(skip)
    return np.random.Generator(bits).random(count)


def pso(
    func: Callable[[np.ndarray], float],
    lb: np.ndarray,
    ub: np.ndarray,
    *,
    seed: int,
    swarmsize: int = 100,
    omega: float = 0.5,
    phip: float = 0.5,
    phig: float = 0.5,
    maxiter: int = 100,
    minstep: float = 1e-8,
    minfunc: float = 1e-8,
) -> tuple[np.ndarray, float]:
    """``pyswarm.pso(func, lb, ub, ..., seed=seed)``'s best point and value (no constraints),
    drawing only the iterations' random factors the loop reads (module docstring).

    Returns ``(x, f)``, what glis unpacks; ``f`` is ``inf`` where pyswarm's would be (no
    feasible particle).
    """
    from pyswarm._pyswarm import pso as compiled_pso

    lb = np.asarray(lb, dtype=np.float64)
    ub = np.asarray(ub, dtype=np.float64)
    if lb.shape != ub.shape or not np.all(ub > lb):
        raise ValueError("pso: lb and ub must have one shape and ub > lb")
    S, D = int(swarmsize), len(lb)
    rng = np.random.default_rng(seed)
    x0 = np.asfortranarray(lb + rng.random((S, D)) * (ub - lb))
    vhigh = np.abs(ub - lb)
    v0 = np.asfortranarray(rng.uniform(-vhigh, vhigh, size=(S, D)))
    start_p = 2 * S * D  # x0 and v0: one draw per double
    start_g = start_p + maxiter * S * D

    def evaluate(x: np.ndarray, n: int) -> float:
        return float(func(np.asarray(x, dtype=np.float64)))

    slabs = min(FIRST_SLABS, maxiter)
    while True:
        shape = (slabs, S, D)
        rnd_p = np.asfortranarray(_factors(seed, start_p, slabs * S * D).reshape(shape))
        rnd_g = np.asfortranarray(_factors(seed, start_g, slabs * S * D).reshape(shape))
        _, _, g, fg, _, _, _, status = compiled_pso(
            evaluate,
            lb,
            ub,
            x0.copy(order="F"),
            v0.copy(order="F"),
            rnd_p,
            rnd_g,
            float(omega),
            float(phip),
            float(phig),
            float(minstep),
            float(minfunc),
            0,  # patience: off, as glis calls it
            0,  # debug
            np.empty(0, dtype=np.int32),  # no integer variables
        )
        if status != MAXITER_STATUS or slabs == maxiter:
            break
        slabs = min(4 * slabs, maxiter)
    return np.asarray(g, dtype=np.float64), float(fg) if fg < INFEASIBLE else float("inf")
