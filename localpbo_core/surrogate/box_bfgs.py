"""Box-constrained BFGS whose curvature carries over from one fit to the next.

The pairwise GP is refit after every duel (paper Alg. "TurPBO", "Fit pairwise GP model using
D_t"). Two consecutive hyperparameter objectives differ by one comparison, so the curvature
learned while solving the previous one is an excellent model of the next. scipy's L-BFGS-B
cannot be given an initial Hessian: each warm refit restarts from a scaled identity and pays
~10-15 objective evaluations in 34 dimensions to relearn it. This solver keeps a dense BFGS
approximation ``B`` of the Hessian (Nocedal & Wright 2006, eq. 6.19, with Powell's damping,
eq. 18.13, so ``B`` stays positive definite), returns it, and accepts it as the start of the
next solve; a warm refit then typically takes 2-5 evaluations.

Bounds are handled by the projected quasi-Newton method of Bertsekas (1982): variables at a
bound whose gradient points outward are held fixed (the epsilon-active set), the quasi-Newton
step is taken in the free variables, and the trial point is projected onto the box; the
Armijo condition is checked along the projected path. Stopping rules are those of scipy's
L-BFGS-B (``ftol`` on the relative reduction of ``f``, ``gtol`` on the largest projected
gradient component), whose defaults BoTorch's ``fit_gpytorch_mll`` uses.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

# scipy's L-BFGS-B defaults (BoTorch's fit_gpytorch_mll passes no options).
DEFAULT_FTOL = 2.220446049250313e-09
DEFAULT_GTOL = 1e-5
_ARMIJO = 1e-4
_MAX_BACKTRACKS = 30
# Largest first step per coordinate while B is still the identity guess (in the units of x).
_MAX_FIRST_STEP = 1.0


@dataclass
class BoxBFGSResult:
    """Outcome of :func:`minimize_box_bfgs`.

    ``hessian`` is the final BFGS approximation of the Hessian of ``f`` (pass it as
    ``hessian0`` of the next, similar problem); ``n_iterations`` counts accepted steps;
    ``message`` says why the solver stopped."""

    x: np.ndarray
    f: float
    g: np.ndarray
    hessian: np.ndarray
    n_evaluations: int
    n_iterations: int
    converged: bool
    message: str


def projected_gradient(x: np.ndarray, g: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """``g`` with the components that push ``x`` out of ``[lo, hi]`` (at a bound) set to 0."""
    pg = g.copy()
    pg[(x <= lo) & (g > 0)] = 0.0
    pg[(x >= hi) & (g < 0)] = 0.0
    return pg


def _damped_bfgs_update(B: np.ndarray, s: np.ndarray, y: np.ndarray) -> np.ndarray:
    """BFGS update of the Hessian approximation with Powell's damping (N&W eqs. 6.19, 18.13):
    ``r = t y + (1 - t) B s`` with ``t`` chosen so that ``s^T r >= 0.2 s^T B s``."""
    Bs = B @ s
    sBs = float(s @ Bs)
    if not np.isfinite(sBs) or sBs <= 0.0:
        return B
    sy = float(s @ y)
    if sy >= 0.2 * sBs:
        r = y
    else:
        t = 0.8 * sBs / (sBs - sy)
        r = t * y + (1.0 - t) * Bs
    sr = float(s @ r)
    if sr <= 1e-12 * sBs:
        return B
    B = B - np.outer(Bs, Bs) / sBs + np.outer(r, r) / sr
    return 0.5 * (B + B.T)


def _free_step(B: np.ndarray, g: np.ndarray, free: np.ndarray) -> np.ndarray | None:
    """Quasi-Newton step ``-B_FF^{-1} g_F`` in the free variables (None if ``B_FF`` is not
    positive definite)."""
    step = np.zeros_like(g)
    if not free.any():
        return step
    Bff = B[np.ix_(free, free)]
    try:
        chol = np.linalg.cholesky(Bff)
    except np.linalg.LinAlgError:
        return None
    z = np.linalg.solve(chol, -g[free])
    step[free] = np.linalg.solve(chol.T, z)
    return step


def minimize_box_bfgs(
    fun: Callable[[np.ndarray], tuple[float, np.ndarray]],
    x0: np.ndarray,
    lower: np.ndarray,
    upper: np.ndarray,
    hessian0: np.ndarray | None = None,
    maxiter: int = 200,
    ftol: float = DEFAULT_FTOL,
    gtol: float = DEFAULT_GTOL,
) -> BoxBFGSResult:
    """Minimise ``fun`` (returning value and gradient) over the box ``[lower, upper]``.

    Args:
        fun: ``x -> (f(x), grad f(x))``; a non-finite value makes the line search back off.
        x0: start (clipped into the box).
        lower, upper: finite bounds, ``lower < upper``.
        hessian0: initial Hessian approximation (symmetric positive definite), typically the
            ``hessian`` of a previous result; None starts from the identity, rescaled after
            the first step (N&W eq. 6.20).
        maxiter: iteration cap.
        ftol: stop when ``(f_k - f_{k+1}) / max(|f_k|, |f_{k+1}|, 1) <= ftol``.
        gtol: stop when the largest projected gradient component is ``<= gtol``.
    """
    lo = np.asarray(lower, dtype=np.float64)
    hi = np.asarray(upper, dtype=np.float64)
    n = lo.size
    x = np.clip(np.asarray(x0, dtype=np.float64), lo, hi)
    fresh = hessian0 is None
    if hessian0 is None:
        B = np.eye(n)
    else:
        B = np.array(hessian0, dtype=np.float64, copy=True)
        if B.shape != (n, n) or not np.all(np.isfinite(B)):
            raise ValueError(f"hessian0 must be a finite ({n}, {n}) matrix")
    f, g = fun(x)
    evals = 1
    if not np.isfinite(f) or not np.all(np.isfinite(g)):
        raise ValueError("the objective is not finite at the start point")
    message = "maximum number of iterations reached"
    converged = False
    steps = 0  # accepted steps
    for _ in range(maxiter):
        pg = projected_gradient(x, g, lo, hi)
        if np.max(np.abs(pg), initial=0.0) <= gtol:
            message, converged = "projected gradient <= gtol", True
            break
        free = pg != 0.0
        step = _free_step(B, g, free)
        if step is None or float(g @ step) >= 0.0:
            B, fresh = np.eye(n), True  # lost positive definiteness: restart from steepest
            step = np.where(free, -g, 0.0)
        if fresh:
            big = np.max(np.abs(step))
            if big > _MAX_FIRST_STEP:
                step *= _MAX_FIRST_STEP / big
        alpha = 1.0
        accepted = False
        for _ in range(_MAX_BACKTRACKS):
            x_new = np.clip(x + alpha * step, lo, hi)
            dx = x_new - x
            slope = float(g @ dx)
            if not np.any(dx):
                break
            f_new, g_new = fun(x_new)
            evals += 1
            if np.isfinite(f_new) and np.all(np.isfinite(g_new)):
                if f_new <= f + _ARMIJO * slope:
                    accepted = True
                    break
                # minimiser of the quadratic through f, slope and f_new, safeguarded
                denom = 2.0 * (f_new - f - slope)
                trial = -slope / denom if denom > 0 else 0.5
                alpha *= float(np.clip(trial, 0.1, 0.5))
            else:
                alpha *= 0.1
        if not accepted:
            message = "line search found no decrease"
            converged = True  # no descent from here: as good as this solver gets
            break
        s, y = x_new - x, g_new - g
        if fresh:
            sy = float(s @ y)
            if sy > 0:
                B = np.eye(n) * (float(y @ y) / sy)
            fresh = False
        B = _damped_bfgs_update(B, s, y)
        f_old = f
        x, f, g = x_new, f_new, g_new
        steps += 1
        if (f_old - f) <= ftol * max(abs(f_old), abs(f), 1.0):
            message, converged = "relative reduction of f <= ftol", True
            break
    return BoxBFGSResult(
        x=x,
        f=float(f),
        g=g,
        hessian=B,
        n_evaluations=evals,
        n_iterations=steps,
        converged=converged,
        message=message,
    )
