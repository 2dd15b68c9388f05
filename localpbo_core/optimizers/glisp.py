"""GLISp baseline (paper Sec. 6, App. D.1 GLISp table; Bemporad & Piga 2021) via ``glis``.

GLISp fits a radial-basis-function surrogate to preferences (linear constraints on the RBF
weights) and picks the next point by particle swarm optimisation of a surrogate +
inverse-distance-weighting exploration acquisition. It queries one point at a time and
compares it to its current best (king of the hill, the App. D.1 accounting: one comparison
per new evaluation).

How the ask/tell wrapper drives ``glis.GLISp`` (``initialize()``, then ``update(pref)``
with ``pref = -1`` when the new point is better than the current best, ``+1`` when worse;
GLISp *minimises*, so "better" is "preferred"):

* Shared initial design (App. D.1): GLISp's own random initial points (its "virtual
  initialisation", table value 10) start with the shared design points of
  ``PreferenceOptimizer`` (in order, including a warm start); the remaining
  ``n_initial_random - initial_design`` points are uniform draws from a seed-derived numpy
  Generator (glis would draw a Latin hypercube from numpy's global RNG). With a shared design
  larger than 10 points, GLISp's random phase is exactly the shared design. The duels of
  the design phase are GLISp's own (point ``k`` against the current best), so GLISp sees
  exactly the base class's outcomes.
* Outcomes are fed lazily: the preference of step ``k`` is passed to ``update`` when the
  next point is asked for, so no acquisition is solved after the last evaluation.
* Determinism: glis calls ``pyswarm.pso`` without a seed (fresh OS entropy with pyswarm
  >= 1.0). During each ``update`` the module attribute ``glis.solvers.pso`` is temporarily
  replaced by a wrapper that passes a seed derived from ``(seed, step)`` and converts
  pyswarm >= 1.0's result object to the ``(x, f)`` tuple glis 2.0.2 unpacks (with pyswarm
  0.6 it seeds numpy's global RNG for the call and restores it); the original is restored
  afterwards. Not thread-safe across concurrent GLISp instances in one process.
* The surrogate fit, one linear program per step (glis's ``get_rbf_weights``), is solved by
  :func:`localpbo_core.optimizers.glisp_lp.rbf_weights`: the same program and solver with the
  same weights to the last bit, without linprog's copies and a presolve that finds nothing
  (docs/performance.md has the figures).
* The particle swarm is pyswarm's compiled loop, driven by
  :func:`localpbo_core.optimizers.glisp_pso.pso`: pyswarm's result to the last bit, without
  drawing the random factors of the 2,000 iterations a swarm almost never reaches. Each
  particle's acquisition value is glis's, computed in one compiled pass
  (:mod:`localpbo_core.optimizers.glisp_acquisition`).
* Comparison tolerance 1e-4 (GLISp table): in glis this is the decision maker's tie
  tolerance (``|f1 - f2| <= tol`` -> ``pref = 0``). Our oracle and the ask/tell contract
  report win/loss as ``pref = -1/+1`` and a "can't tell" answer
  (:class:`~localpbo_core.optimizers.base.Indifferent`, with ``tie_threshold > 0``) as
  ``pref = 0``: GLISp's own "equal" preference constraint ``|f_hat(x) - f_hat(y)| <= sigma``
  (Bemporad & Piga 2021, Sec. 3.1), which keeps the current best. The surrogate-range floor
  ``epsDeltaF`` is glis's default 1e-4.
* RBF recalibration (Bemporad & Piga 2021, Sec. 3.3; glis's ``RBFcalibrate``): glis picks
  the RBF shape factor θ among 10 values by leave-one-out cross-validation of the comparisons
  at four steps ``n + k (E - n) / 4``, ``k = 0..3``, with ``n = n_initial_random`` and ``E =
  expected_max_evals``; a recalibration at ``N`` samples solves ``10 (N - 1)`` linear programs
  of ``N`` points each, against one per ordinary step. ``E`` also sets the separation of a
  strict preference in the RBF weights' linear program, ``σ = 1 / E``. The GLISp table of the
  paper names no ``E``, so glis's own default ``E = 100`` is used, which puts every
  recalibration in the first 100 evaluations and keeps the per-step cost at one linear
  program and one swarm (the paper's GLISp times, e.g. 29 s for 496 evaluations on Hopper,
  are of that order). ``expected_max_evals=None`` sets ``E`` to the run's budget, as glis's
  ``solve()`` does: recalibrations then spread over the whole run and grow with the square of
  the evaluations (about 900 s for Hopper here). ``ablation_glisp_calibration`` compares the
  two.
"""

from __future__ import annotations

import contextlib
import importlib
import inspect
import sys
import types
from collections.abc import Callable, Iterator
from typing import Any, Protocol, Unpack, cast

import numpy as np

from localpbo_core.optimizers import glisp_acquisition, glisp_pso
from localpbo_core.optimizers.base import Ask, Candidate, Duel, DuelAnswer, Outcome
from localpbo_core.optimizers.glisp_lp import rbf_weights
from localpbo_core.optimizers.glisp_pso import reproduces_installed_pyswarm
from localpbo_core.optimizers.preference_optimizer import (
    PreferenceOptimizer,
    RunOptions,
    check_one_per_ask,
    step_generator,
)
from localpbo_core.validation import check_float, check_int

#: Tag mixed into the seed of GLISp's extra random initial points.
GLISP_INIT_TAG = 0x611F


class _GlisSolvers(Protocol):
    """What this wrapper uses of the untyped module ``glis.solvers``."""

    GLISp: Callable[..., Any]
    pso: Callable[..., Any]


def _glis_solvers() -> _GlisSolvers:
    """Import ``glis.solvers``. glis 2.0.2 does ``from pyDOE import lhs``, but pydoe >= 1.6
    renamed its module to ``pydoe``; if only the new name exists it is aliased (glis's ``lhs``
    is never called here: the initial points are supplied by this wrapper)."""
    try:
        importlib.import_module("pyDOE")
    except ModuleNotFoundError:
        sys.modules["pyDOE"] = importlib.import_module("pydoe")
    return cast(_GlisSolvers, importlib.import_module("glis.solvers"))


def _pso_with_seed(pso: Callable[..., Any], seed: int) -> Callable[..., tuple[Any, Any]]:
    """``pso`` as glis calls it (``z, cost = pso(...)``), seeded.

    glis's acquisition is evaluated by
    :func:`~localpbo_core.optimizers.glisp_acquisition.fast_acquisition` where it gives glis's
    values. With the pyswarm release :mod:`localpbo_core.optimizers.glisp_pso` reproduces, the
    swarm is its :func:`~localpbo_core.optimizers.glisp_pso.pso` (pyswarm's result bit for bit,
    without drawing the random factors of iterations the swarm never reaches). Otherwise
    pyswarm's own: pyswarm >= 1.0 takes ``seed=`` and returns a result object (``.x``,
    ``.fun``), which glis 2.0.2 cannot unpack; pyswarm 0.6 returns ``(x, f)`` and draws from
    numpy's global RNG, which is then seeded for the call and restored afterwards.
    """
    fast_swarm = reproduces_installed_pyswarm()
    takes_seed = "seed" in inspect.signature(pso).parameters

    def seeded(func: Callable[..., float], *args: Any, **kwargs: Any) -> tuple[Any, Any]:
        func = glisp_acquisition.fast_acquisition(func) or func
        if fast_swarm:
            return glisp_pso.pso(func, *args, seed=seed, **kwargs)
        if takes_seed:
            res = pso(func, *args, seed=seed, **kwargs)
        else:
            state = np.random.get_state()  # noqa: NPY002 - restored below
            np.random.seed(seed)  # noqa: NPY002 - pyswarm 0.6 only knows the global RNG
            try:
                res = pso(func, *args, **kwargs)
            finally:
                np.random.set_state(state)  # noqa: NPY002
        if isinstance(res, tuple):
            return res[0], res[1]
        return res.x, res.fun

    return seeded


def _fit_rbf_weights(
    glis: Any, M: np.ndarray, n: int, prefs: np.ndarray, ties: np.ndarray, ibest: int
) -> np.ndarray:
    """``glis.solvers.GLISp.get_rbf_weights`` of ``glis``, by
    :func:`localpbo_core.optimizers.glisp_lp.rbf_weights` (the same weights, faster)."""
    return rbf_weights(M, n, prefs, ties, ibest, float(glis.sepvalue))


@contextlib.contextmanager
def _seeded_pso(seed: int) -> Iterator[None]:
    """Make glis's particle swarm use ``seed`` for the duration of the block."""
    solvers = _glis_solvers()
    original = solvers.pso
    solvers.pso = _pso_with_seed(original, seed)
    try:
        yield
    finally:
        solvers.pso = original


class GLISpOptimizer(PreferenceOptimizer):
    """GLISp (``glis`` 2.0.2) behind the ask/tell contract.

    Args:
        dim, seed, budget, initial_design, warm_start: see ``PreferenceOptimizer``.
        n_initial_random: GLISp's random initial points (table: 10); at least the shared
            design is used, i.e. ``max(n_initial_random, initial_design)``.
        delta: GLISp's exploration weight of the IDW term (glis default 0.5).
        pso_iters: maximum particle swarm iterations per acquisition (glis default 2000).
        pso_swarm_size: particles (glis default 20).
        expected_max_evals: glis's ``expected_max_evals`` E, which places its four RBF
            recalibrations and sets the preference separation 1/E (module docstring); None:
            the run's budget. Default 100, glis's own.
        batch_size: must be 1 (GLISp queries one point at a time); accepted so that a
            common ``batch_size=1`` option can be passed to every algorithm.
    """

    name = "glisp"

    def __init__(
        self,
        dim: int,
        seed: int,
        budget: int,
        n_initial_random: int = 10,
        delta: float = 0.5,
        pso_iters: int = 2000,
        pso_swarm_size: int = 20,
        expected_max_evals: int | None = 100,
        batch_size: int = 1,
        **run: Unpack[RunOptions],
    ) -> None:
        super().__init__(dim, seed, budget, **run)
        check_one_per_ask(batch_size, "GLISp queries one point at a time")
        n_initial_random = check_int("n_initial_random", n_initial_random, minimum=2)
        pso_iters = check_int("pso_iters", pso_iters)
        pso_swarm_size = check_int("pso_swarm_size", pso_swarm_size)
        delta = check_float("delta", delta, minimum=0.0)
        if expected_max_evals is None:
            expected_max_evals = self._budget
        expected_max_evals = check_int("expected_max_evals", expected_max_evals)
        self.n_initial_random = max(n_initial_random, self.initial_design)
        rng = np.random.default_rng(np.random.SeedSequence([self.seed, GLISP_INIT_TAG]))
        extra = rng.random((self.n_initial_random - self.initial_design, self.dim))
        self._glis_initial = np.vstack([self._design, extra])

        self._glis = _glis_solvers().GLISp(
            bounds=(np.zeros(self.dim), np.ones(self.dim)),
            n_initial_random=self.n_initial_random,
            delta=float(delta),
            epsDeltaF=1e-4,
            expected_max_evals=expected_max_evals,
            PSOiters=int(pso_iters),
            PSOswarmsize=int(pso_swarm_size),
            display=0,
        )
        initial = self._glis_initial

        def _initial_samples() -> np.ndarray:
            glis = self._glis
            glis.KnownFeasible = list(np.ones(glis.n_initial_random))
            glis.X = [row.copy() for row in initial]
            return (initial - glis.d0) / glis.dd  # glis works in [-1, 1]^d

        self._glis.initialize_ = _initial_samples
        self._glis.get_rbf_weights = types.MethodType(_fit_rbf_weights, self._glis)
        self._glis.initialize()
        self._fed = 0  # outcomes passed to glis so far

    @property
    def glis(self) -> object:
        """The wrapped ``glis.solvers.GLISp`` instance (read-only use)."""
        return self._glis

    def _feed(self) -> np.ndarray:
        """Pass every outcome not yet seen by glis; return glis's next point."""
        glis = self._glis
        xnext = np.asarray(glis.xnext, dtype=np.float64)
        while self._fed < len(self._outcomes):
            out = self._outcomes[self._fed]
            new_id = int(glis.iter)
            pair = {out.winner, out.loser} if isinstance(out, Outcome) else {out.first, out.second}
            if pair != {new_id, int(glis.ibest)}:
                raise RuntimeError(
                    f"glisp: outcome {out} is not the duel of candidate {new_id} against "
                    f"GLISp's best {glis.ibest}"
                )
            if isinstance(out, Outcome):
                pref = -1 if out.winner == new_id else 1
            else:
                pref = 0  # "can't tell": GLISp's equality constraint
            with _seeded_pso(self._pso_seed(new_id)):
                xnext = np.asarray(glis.update(pref), dtype=np.float64)
            self._fed += 1
        if int(glis.ibest) != self._require_incumbent():
            raise RuntimeError("glisp: GLISp's best and the incumbent disagree")
        return xnext

    def _pso_seed(self, step: int) -> int:
        return int(step_generator(self.seed, step).integers(0, 2**31 - 1))

    def _propose(self, remaining: int) -> Ask:
        xnext = self._feed()
        if len(self._candidates) < self.n_initial_random:
            theta = self._glis_initial[len(self._candidates)]
        else:
            theta = np.clip(xnext.reshape(self.dim), 0.0, 1.0)
        new = self._register([theta])
        return Ask(tuple(new), (Duel(new[0].id, self._require_incumbent()),))

    def _on_step_complete(
        self, candidates: tuple[Candidate, ...], outcomes: tuple[DuelAnswer, ...]
    ) -> None:
        self._update_king(outcomes)
