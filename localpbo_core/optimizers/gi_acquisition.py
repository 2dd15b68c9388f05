"""The preferential gradient-information acquisition of GIPBO (paper Sec. 5.1, eq.
GI_PBO_acf_detailed) and its candidate sets (App. C.2, "Candidate-set construction").

``alpha(x | x_t, D) = tr Sigma_11(x_t | D) - sum_o P(o) tr Sigma_11(x_t | D + o)`` where ``o``
ranges over the two outcomes of the virtual duel between ``x`` and its opponent (``x > opp``
and ``opp > x``), ``P(o)`` is the Laplace predictive preference probability (eq. (5) "likelihood"
marginalised over the posterior) and ``D + o`` is refitted (Laplace MAP) at FIXED
hyperparameters. All refits of a candidate set are done in batch by
:func:`localpbo_core.surrogate.virtual_refit.virtual_refit`.

"Virtual preference likelihood threshold" (GIPBO table, value 0.1; not explained in the
paper). Documented meaning chosen here: an outcome branch whose probability ``P(o)`` is
below the threshold is not refitted and the other branch gets weight 1 (the weights of the
kept branches are renormalised). The dropped term is at most ``0.1 tr Sigma_11`` and
refitting a nearly impossible outcome only adds cost. ``likelihood_threshold=0`` gives eq.
GI_PBO_acf_detailed exactly.

"Can't tell" answers: when the surrogate has an indifference threshold ``eps > 0`` (the
ordinal likelihood of :mod:`localpbo_core.surrogate.ordinal`), the virtual duel has three
outcomes, ``x > opp``, ``opp > x`` and a tie, with the predictive probabilities
``Phi((+-mu_g - eps) / s)`` and the rest (``s^2 = 2 + var_g``); each is refitted with its own
likelihood and the expectation runs over all three.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import torch
from torch import Tensor

from localpbo_core.surrogate.data import DUPLICATE_ATOL
from localpbo_core.surrogate.protocol import Surrogate
from localpbo_core.surrogate.virtual_refit import gradient_covariance_trace, virtual_refit
from localpbo_core.validation import check_float

#: Paper App. C.2: radii of the hyperspheres for d > 2 and the search bounds.
DEFAULT_RADII = (0.05, 0.1, 0.15, 0.2)
DEFAULT_BOUNDS = (0.05, 0.2)
#: Upper bound on ``batch * P * P`` float64 entries per refit chunk (memory, ~32 MB).
_CHUNK_ENTRIES = 4_000_000


def sphere_directions(n: int, dim: int, rng: np.random.Generator) -> np.ndarray:
    """``n`` uniform directions on the unit sphere ``S^{d-1}``: normalised standard normal
    vectors (the Gaussian method, Marsaglia 1972's reference construction)."""
    z = rng.standard_normal((n, dim))
    norm = np.linalg.norm(z, axis=1, keepdims=True)
    norm[norm == 0.0] = 1.0
    return z / norm


def hypersphere_candidates(
    center: np.ndarray,
    rng: np.random.Generator,
    radii: Sequence[float] = DEFAULT_RADII,
    resolution: int = 50,
    max_candidates: int = 512,
    search_bounds: tuple[float, float] = DEFAULT_BOUNDS,
) -> np.ndarray:
    """Candidate set of App. C.2, projected onto ``[0, 1]^d``.

    ``d <= 2``: 2,500 points on 10 concentric circles with radii spanning ``search_bounds``.
    ``d > 2``: ``min(d * resolution, max_candidates)`` points split evenly over the spheres of
    ``radii`` (paper: 0.05, 0.1, 0.15, 0.2; resolution 50; cap 512).
    """
    d = int(center.shape[0])
    if d <= 2:
        rads = np.linspace(search_bounds[0], search_bounds[1], 10)
        per = [250] * 10
    else:
        rads = np.asarray(radii, dtype=np.float64)
        total = min(d * resolution, max_candidates)
        base, extra = divmod(total, len(rads))
        per = [base + (1 if i < extra else 0) for i in range(len(rads))]
    pts = [center + r * sphere_directions(n, d, rng) for r, n in zip(rads, per, strict=True)]
    return np.clip(np.concatenate(pts, axis=0), 0.0, 1.0)


def random_local_query(
    center: np.ndarray,
    rng: np.random.Generator,
    search_bounds: tuple[float, float] = DEFAULT_BOUNDS,
) -> np.ndarray:
    """GIPBOr's query (App. C.3): uniform direction, radius uniform in ``search_bounds``,
    projected onto ``[0, 1]^d``."""
    u = sphere_directions(1, center.shape[0], rng)[0]
    r = rng.uniform(search_bounds[0], search_bounds[1])
    return np.clip(center + r * u, 0.0, 1.0)


def _match_index(points: Tensor, x: Tensor) -> int | None:
    """Row of ``points`` within ``DUPLICATE_ATOL`` (every coordinate) of ``x``, or None."""
    dist = (points - x).abs().amax(-1)
    j = int(torch.argmin(dist))
    return j if float(dist[j]) <= DUPLICATE_ATOL else None


@torch.no_grad()
def gi_pbo_acquisition(
    surrogate: Surrogate,
    center: Tensor,
    candidates: Tensor,
    opponent: Tensor,
    likelihood_threshold: float = 0.0,
) -> Tensor:
    """Eq. (16) "GIPBO acquisition" for every candidate (``(N,)``; larger is better).

    Args:
        surrogate: the current fit (its hyperparameters stay fixed in the virtual refits).
        center: ``(d,)`` the point ``x_t`` whose gradient covariance is reduced.
        candidates: ``(N, d)`` points ``x``.
        opponent: ``(d,)`` the point each candidate is virtually dueled against (GIPBO passes
            the local incumbent, which is ``x_t`` for the first query of a phase). It may be
            a new point (not in the data), e.g. a center not evaluated yet.
        likelihood_threshold: in ``[0, 0.5)``; see the module docstring.

    Candidates that coincide (within ``DUPLICATE_ATOL``) with a training point or with the
    opponent get ``-inf``.
    """
    check_float(
        "likelihood_threshold", likelihood_threshold, minimum=0.0, maximum=0.5, maximum_open=True
    )
    X = surrogate.train_inputs
    p, d = X.shape
    if candidates.ndim != 2 or candidates.shape[1] != d:
        raise ValueError(f"candidates must have shape (N, {d}), got {tuple(candidates.shape)}")
    N = candidates.shape[0]
    j_opp = _match_index(X, opponent)
    ref = X if j_opp is not None else torch.cat([X, opponent.unsqueeze(0)], dim=0)
    near = (candidates.unsqueeze(1) - ref.unsqueeze(0)).abs().amax(-1).amin(-1) <= DUPLICATE_ATOL
    valid = torch.nonzero(~near).flatten()
    out = torch.full((N,), -torch.inf, dtype=torch.float64)
    if valid.numel() == 0:
        return out
    cand = candidates[valid]
    n = cand.shape[0]
    if j_opp is None:
        new_points = torch.stack([opponent.expand(n, d), cand], dim=1)  # (n, 2, d)
        i_opp, i_x = p, p + 1
    else:
        new_points = cand.unsqueeze(1)
        i_opp, i_x = j_opp, p
    opp = opponent.expand(n, d)
    prob_x = surrogate.preference_probability(cand, opp)  # P(x > opp)
    if surrogate.tie_threshold > 0:  # outcome 2: "can't tell"
        prob_opp = surrogate.preference_probability(opp, cand)
        prob_tie = (1.0 - prob_x - prob_opp).clamp_min(0.0)
        probs = torch.stack([prob_x, prob_opp, prob_tie], dim=1)
    else:
        probs = torch.stack([prob_x, 1.0 - prob_x], dim=1)  # outcome 0: x wins, 1: opp wins
    keep = probs >= likelihood_threshold
    weights = torch.where(keep, probs, torch.zeros_like(probs))
    weights = weights / weights.sum(1, keepdim=True)
    rows, outcome = torch.nonzero(keep, as_tuple=True)
    winners = torch.where(outcome == 0, i_x, i_opp).long()
    losers = torch.where(outcome == 0, i_opp, i_x).long()
    vtie = outcome == 2 if probs.shape[1] == 3 else None
    P = p + new_points.shape[1]
    chunk = max(1, _CHUNK_ENTRIES // (P * P))
    traces = torch.empty(rows.shape[0], dtype=torch.float64)
    for s in range(0, rows.shape[0], chunk):
        sl = slice(s, s + chunk)
        fit = virtual_refit(
            surrogate,
            new_points[rows[sl]],
            winners[sl],
            losers[sl],
            virtual_tie=None if vtie is None else vtie[sl],
        )
        traces[sl] = gradient_covariance_trace(surrogate, fit, center)
    expected = torch.zeros(n, dtype=torch.float64)
    expected.index_add_(0, rows, weights[rows, outcome] * traces)
    current = torch.diagonal(surrogate.gradient_covariance(center)).sum()
    out[valid] = current - expected
    return out
