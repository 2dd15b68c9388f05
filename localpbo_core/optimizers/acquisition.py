"""Acquisition functions and their optimisation inside a box (TuRPBO, paper App. C.5).

* Thompson sampling on pathwise posterior sample paths (TuRBO's acquisition, App. C.5;
  raw samples 1024 and 5 L-BFGS-B restarts per the TuRPBO table).
* EUBO (Lin et al. 2022, Astudillo et al. 2023, paper Sec. 6 baselines) for a candidate
  against the incumbent, analytic for q = 1:
  ``EUBO(x) = E[max(f(x), f(x*))] = m* + (m - m*) Phi(z) + s phi(z)``,
  ``s^2 = v + v* - 2 c``, ``z = (m - m*) / s``;
  and a fixed-base-sample Monte Carlo qEUBO for q > 1:
  ``qEUBO(X) = E[max(f(x*), f(x_1), ..., f(x_q))]`` with ``f = m + chol(C) Z``.
* Expected improvement of the latent utility over the posterior mean at the incumbent
  (TuRPBO's EI ablation, paper App. D.7), analytic for q = 1:
  ``EI(x) = E[max(f(x) - m*, 0)] = (m - m*) Phi(z) + s phi(z)``, ``z = (m - m*) / s``,
  ``m = mu(x)``, ``s^2 = var f(x)``, ``m* = mu(x*)`` (a number, not a random variable).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import torch
from scipy.optimize import Bounds, minimize
from torch import Tensor

from localpbo_core.surrogate.sampling import SamplePaths

_SQRT2 = 2.0**0.5
_INV_SQRT_2PI = (2.0 * torch.pi) ** -0.5


def eubo_from_moments(mean: Tensor, cov: Tensor) -> Tensor:
    """Analytic EUBO of each point against the incumbent.

    Args:
        mean: ``(1 + N,)`` joint posterior mean, index 0 is the incumbent.
        cov: ``(1 + N, 1 + N)`` joint posterior covariance.

    Returns:
        ``(N,)`` values ``E[max(f(x_i), f(x*))]``.
    """
    m0 = mean[0]
    m = mean[1:]
    var = torch.diagonal(cov)
    s2 = (var[1:] + var[0] - 2.0 * cov[1:, 0]).clamp_min(1e-12)
    s = s2.sqrt()
    z = (m - m0) / s
    cdf = 0.5 * (1.0 + torch.erf(z / _SQRT2))
    pdf = _INV_SQRT_2PI * torch.exp(-0.5 * z * z)
    return m0 + (m - m0) * cdf + s * pdf


def expected_improvement(mean: Tensor, var: Tensor, best: float) -> Tensor:
    """Analytic EI ``E[max(f(x) - best, 0)] = (m - best) Phi(z) + s phi(z)``, ``z = (m -
    best) / s``, ``s = sqrt(max(var, 1e-12))``, for a Gaussian ``f(x) ~ N(m, var)``
    elementwise; differentiable in ``mean`` and ``var``."""
    s = var.clamp_min(1e-12).sqrt()
    u = mean - best
    z = u / s
    cdf = 0.5 * (1.0 + torch.erf(z / _SQRT2))
    pdf = _INV_SQRT_2PI * torch.exp(-0.5 * z * z)
    return u * cdf + s * pdf


def qeubo_from_moments(mean: Tensor, cov: Tensor, base_samples: Tensor) -> Tensor:
    """Monte Carlo qEUBO with fixed base samples.

    Args:
        mean: ``(B, 1 + q)`` joint means; column 0 is the incumbent.
        cov: ``(B, 1 + q, 1 + q)`` joint covariances.
        base_samples: ``(S, 1 + q)`` standard normal draws (fixed across evaluations).

    Returns:
        ``(B,)`` estimates of ``E[max_j f_j]``.
    """
    k = cov.shape[-1]
    jitter = 1e-9 * torch.eye(k, dtype=cov.dtype)
    chol = torch.linalg.cholesky(0.5 * (cov + cov.transpose(-1, -2)) + jitter)
    samples = mean[:, None, :] + torch.einsum("bij,sj->bsi", chol, base_samples)
    return samples.max(dim=-1).values.mean(dim=-1)


def _lbfgsb_multistart(
    value_and_grad: Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]],
    values: Callable[[np.ndarray], np.ndarray],
    starts: np.ndarray,
    lb: np.ndarray,
    ub: np.ndarray,
    maxiter: int,
) -> tuple[np.ndarray, np.ndarray]:
    """One L-BFGS-B run on the sum of a separable batched objective (numpy float64).

    ``value_and_grad`` maps ``(R, *shape)`` points to their values ``(R,)`` and gradients
    ``(R, *shape)``; ``values`` gives the values only. A start whose optimisation did not
    improve is kept (L-BFGS-B may stop early), so no row ends worse than its start.
    """
    shape = starts.shape
    lo = np.broadcast_to(lb, shape).reshape(-1)
    hi = np.broadcast_to(ub, shape).reshape(-1)

    def fun(flat: np.ndarray) -> tuple[float, np.ndarray]:
        val, grad = value_and_grad(flat.reshape(shape))
        return -float(val.sum()), -np.asarray(grad, dtype=np.float64).reshape(-1)

    x0 = np.clip(starts.reshape(-1), lo, hi)
    res = minimize(
        fun,
        x0,
        jac=True,
        method="L-BFGS-B",
        bounds=Bounds(lo, hi),
        options={"maxiter": maxiter},
    )
    x = np.clip(res.x.reshape(shape), np.broadcast_to(lb, shape), np.broadcast_to(ub, shape))
    vals = values(x)
    v0 = values(starts)
    better = vals >= v0
    x = np.where(better.reshape((-1,) + (1,) * (len(shape) - 1)), x, starts)
    return x, np.maximum(vals, v0)


def maximize_in_box(
    objective: Callable[[Tensor], Tensor],
    starts: np.ndarray,
    lb: np.ndarray,
    ub: np.ndarray,
    maxiter: int = 200,
) -> tuple[np.ndarray, np.ndarray]:
    """Maximise a separable batched objective from several starts with one L-BFGS-B run.

    ``objective`` maps ``(R, *shape)`` points to ``(R,)`` values, each depending only on its
    own row, so maximising the sum maximises every row (the multi-start scheme of BoTorch's
    ``gen_candidates_scipy``). Gradients come from torch autograd.

    Returns:
        the optimised points ``(R, *shape)`` and their values ``(R,)``.
    """

    def value_and_grad(x_np: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        x = torch.tensor(x_np, dtype=torch.float64, requires_grad=True)
        val = objective(x)
        (grad,) = torch.autograd.grad(val.sum(), x)
        return val.detach().numpy(), grad.numpy()

    def values(x_np: np.ndarray) -> np.ndarray:
        with torch.no_grad():
            return objective(torch.tensor(x_np, dtype=torch.float64)).numpy()

    return _lbfgsb_multistart(value_and_grad, values, starts, lb, ub, maxiter)


def thompson_batch(
    path: Callable[[Tensor], Tensor],
    raw: np.ndarray,
    lb: np.ndarray,
    ub: np.ndarray,
    num_restarts: int = 5,
    maxiter: int = 200,
) -> np.ndarray:
    """One maximiser per sample path: raw candidates -> best ``num_restarts`` per path ->
    L-BFGS-B inside the box on that path (TuRPBO table: 1024 raw, 5 restarts).

    If ``path`` is a :class:`~localpbo_core.surrogate.sampling.SamplePaths` (pathwise
    sampling of the paper Sec. 4 posterior), its float64 numpy ``values`` and closed-form
    ``value_and_grad`` are used; for any other callable the values come from ``path`` and
    the gradients from torch autograd.

    Args:
        path: maps ``(N, d)`` to ``(N, P)``: P pathwise Thompson samples.
        raw: ``(N, d)`` raw candidates inside the box.

    Returns:
        ``(P, d)``: the maximiser of each path.
    """
    raw = np.asarray(raw, dtype=np.float64)
    if isinstance(path, SamplePaths):
        return _thompson_analytic(path, raw, lb, ub, num_restarts, maxiter)
    vals = _path_values(path, raw)
    out = []
    for j in range(vals.shape[1]):
        starts = raw[np.argsort(-vals[:, j], kind="stable")[:num_restarts]]

        def obj(x: Tensor, j: int = j) -> Tensor:
            return path(x)[:, j]

        xs, fs = maximize_in_box(obj, starts, lb, ub, maxiter)
        out.append(xs[int(np.argmax(fs))])
    return np.stack(out)


def _path_values(path: Callable[[Tensor], Tensor], raw: np.ndarray) -> np.ndarray:
    """``(N, P)`` float64 values of the sample paths at ``raw``: the closed form of
    :class:`~localpbo_core.surrogate.sampling.SamplePaths`, else ``path`` without gradients."""
    if isinstance(path, SamplePaths):
        return np.asarray(path.values(raw), dtype=np.float64)
    with torch.no_grad():
        return path(torch.tensor(raw, dtype=torch.float64)).numpy()


def thompson_discrete(path: Callable[[Tensor], Tensor], raw: np.ndarray) -> np.ndarray:
    """Thompson sampling on the raw candidates only (TuRBO's scheme, no local refinement):
    path ``j`` takes the raw candidate where it is largest among those not yet taken by
    paths ``0..j-1`` (a batch without repeats). Returns ``(P, d)``.

    Args:
        path: maps ``(N, d)`` to ``(N, P)``: P pathwise Thompson samples
            (:class:`~localpbo_core.surrogate.sampling.SamplePaths` or any callable).
        raw: ``(N, d)`` candidates, ``N >= P``.
    """
    raw = np.asarray(raw, dtype=np.float64)
    vals = _path_values(path, raw)
    if vals.shape[1] > raw.shape[0]:
        raise ValueError(f"{vals.shape[1]} paths need at least as many raw candidates")
    taken = np.zeros(raw.shape[0], dtype=bool)
    out = []
    for j in range(vals.shape[1]):
        i = int(np.argmax(np.where(taken, -np.inf, vals[:, j])))
        taken[i] = True
        out.append(raw[i])
    return np.stack(out)


def _thompson_analytic(
    paths: SamplePaths,
    raw: np.ndarray,
    lb: np.ndarray,
    ub: np.ndarray,
    num_restarts: int,
    maxiter: int,
) -> np.ndarray:
    """:func:`thompson_batch` on the closed-form values and gradients of ``paths``."""
    vals = paths.values(raw)
    out = []
    for j in range(vals.shape[1]):
        starts = raw[np.argsort(-vals[:, j], kind="stable")[:num_restarts]]

        def vg(x: np.ndarray, j: int = j) -> tuple[np.ndarray, np.ndarray]:
            return paths.value_and_grad(x, j)

        def v(x: np.ndarray, j: int = j) -> np.ndarray:
            return paths.values(x, j)

        xs, fs = _lbfgsb_multistart(vg, v, starts, lb, ub, maxiter)
        out.append(xs[int(np.argmax(fs))])
    return np.stack(out)


def eubo_batch(
    mean_cov: Callable[[Tensor], tuple[Tensor, Tensor]],
    incumbent: np.ndarray,
    raw: np.ndarray,
    lb: np.ndarray,
    ub: np.ndarray,
    q: int,
    base_samples: Tensor,
    rng: np.random.Generator,
    num_restarts: int = 5,
    num_raw_batches: int = 256,
) -> np.ndarray:
    """Maximise (q)EUBO against the incumbent in the box; returns ``(q, d)``.

    q = 1 uses :func:`eubo_from_moments` (analytic); q > 1 uses
    :func:`qeubo_from_moments` with the given fixed ``base_samples`` ``(S, 1 + q)``.
    ``mean_cov`` is the surrogate's joint posterior ``Xq (k, d) -> (mean (k,), cov (k, k))``.
    """
    inc = torch.tensor(incumbent, dtype=torch.float64)[None, :]
    d = incumbent.size

    if q == 1:

        def obj1(x: Tensor) -> Tensor:
            m, c = mean_cov(torch.cat([inc, x.reshape(-1, d)], dim=0))
            return eubo_from_moments(m, c)

        with torch.no_grad():
            vals = obj1(torch.tensor(raw, dtype=torch.float64)).numpy()
        top = np.argsort(-vals, kind="stable")[:num_restarts]
        xs, fs = maximize_in_box(obj1, raw[top], lb, ub)
        return xs[int(np.argmax(fs))][None, :]

    def objq(x: Tensor) -> Tensor:
        b = x.shape[0]
        m, c = mean_cov(torch.cat([inc, x.reshape(-1, d)], dim=0))
        idx = torch.arange(b * q).reshape(b, q) + 1
        idx = torch.cat([torch.zeros(b, 1, dtype=torch.long), idx], dim=1)
        mb = m[idx]
        cb = c[idx[:, :, None], idx[:, None, :]]
        return qeubo_from_moments(mb, cb, base_samples)

    nb = min(num_raw_batches, raw.shape[0] // q)
    perm = rng.permutation(raw.shape[0])[: nb * q]
    batches = raw[perm].reshape(nb, q, d)
    with torch.no_grad():
        vals = objq(torch.tensor(batches, dtype=torch.float64)).numpy()
    top = np.argsort(-vals, kind="stable")[:num_restarts]
    xs, fs = maximize_in_box(objq, batches[top], lb, ub)
    return xs[int(np.argmax(fs))]


def ei_batch(
    mean_var: Callable[[Tensor], tuple[Tensor, Tensor]],
    best: float,
    raw: np.ndarray,
    lb: np.ndarray,
    ub: np.ndarray,
    num_restarts: int = 5,
    maxiter: int = 200,
) -> np.ndarray:
    """Maximise :func:`expected_improvement` over ``best`` in the box: EI at the raw
    candidates, the best ``num_restarts`` start one multi-start L-BFGS-B run (gradients by
    autograd through ``mean_var``). ``mean_var`` maps ``(N, d)`` to the marginal posterior
    means ``(N,)`` and variances ``(N,)``. Returns ``(1, d)``."""
    raw = np.asarray(raw, dtype=np.float64)

    def obj(x: Tensor) -> Tensor:
        m, v = mean_var(x)
        return expected_improvement(m, v, best)

    with torch.no_grad():
        vals = obj(torch.tensor(raw, dtype=torch.float64)).numpy()
    top = np.argsort(-vals, kind="stable")[:num_restarts]
    xs, fs = maximize_in_box(obj, raw[top], lb, ub, maxiter)
    return xs[int(np.argmax(fs))][None, :]
