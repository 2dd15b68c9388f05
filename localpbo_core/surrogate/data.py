"""Input validation and consolidation of duel data for the pairwise GP (paper Sec. 4).

The GP works on the *unique* input locations ``X = [x_i]_{i=1..P}`` that appear in duels
(paper Sec. 4, "Prior"). Points closer than ``atol`` in every coordinate are merged (as BoTorch's
``consolidate_duplicates`` with ``atol=1e-4``); duels that become self-duels after merging carry
no information and are dropped (BoTorch keeps them and reads them as a loss, which is wrong).
"Can't tell" answers (ties, see :mod:`.ordinal`) are kept as duel rows flagged in ``tie``; a
tie between two points that merge is dropped like any self-duel.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch
from torch import Tensor

DUPLICATE_ATOL = 1e-4


@dataclass(frozen=True)
class DuelData:
    """Consolidated duel data.

    Attributes:
        X: unique points ``(p, d)`` float64.
        winners, losers: ``(m,)`` long indices into ``X`` (no self-duels); for a tie row
            they are the duel's first and second point.
        index_map: ``(n,)`` long, original row of the input ``X`` -> row of the unique ``X``.
        tie: ``(m,)`` bool, True for "can't tell" rows.
    """

    X: Tensor
    winners: Tensor
    losers: Tensor
    index_map: Tensor
    tie: Tensor


def validate_points(X: object, name: str = "X", dim: int | None = None) -> Tensor:
    """Check an ``(n, d)`` float64 tensor of finite points in ``[0, 1]^d``; return it."""
    if not isinstance(X, Tensor):
        raise ValueError(f"{name} must be a torch.Tensor, got {type(X).__name__}")
    if X.dtype != torch.float64:
        raise ValueError(f"{name} must have dtype torch.float64, got {X.dtype}")
    if X.ndim != 2 or X.shape[0] < 1 or X.shape[1] < 1:
        raise ValueError(f"{name} must have shape (n, d) with n, d >= 1, got {tuple(X.shape)}")
    if dim is not None and X.shape[1] != dim:
        raise ValueError(f"{name} must have d={dim} columns, got {X.shape[1]}")
    if not torch.isfinite(X).all():
        raise ValueError(f"{name} contains NaN or inf")
    if (X < 0).any() or (X > 1).any():
        raise ValueError(f"{name} must lie in [0, 1]^d (found values outside)")
    return X


def validate_comparisons(
    comparisons: object, n: int, name: str = "comparisons", min_rows: int = 1
) -> Tensor:
    """Check an ``(m, 2)`` long tensor of ``[winner, loser]`` indices in ``[0, n)`` (``name``
    ``"ties"``: ``[first, second]`` rows), ``m >= min_rows``."""
    if not isinstance(comparisons, Tensor):
        raise ValueError(f"{name} must be a torch.Tensor, got {type(comparisons).__name__}")
    if comparisons.dtype != torch.long:
        raise ValueError(f"{name} must have dtype torch.long, got {comparisons.dtype}")
    if comparisons.ndim != 2 or comparisons.shape[1] != 2 or comparisons.shape[0] < min_rows:
        raise ValueError(
            f"{name} must have shape (m, 2) with m >= {min_rows}, got {tuple(comparisons.shape)}"
        )
    if (comparisons < 0).any() or (comparisons >= n).any():
        raise ValueError(f"{name} contain indices out of range [0, {n})")
    return comparisons


def consolidate(
    X: Tensor, comparisons: Tensor, atol: float = DUPLICATE_ATOL, ties: Tensor | None = None
) -> DuelData:
    """Merge points within ``atol`` (each coordinate) of an earlier point, drop self-duels.
    ``ties`` ``(k, 2)`` are "can't tell" rows ``[first, second]``, appended after the
    comparisons (flagged in ``DuelData.tie``).

    Raises:
        ValueError: if no duel between distinct points remains.
    """
    n = X.shape[0]
    close = torch.cdist(X, X, p=float("inf")) <= atol  # (n, n), max-abs distance
    rep = torch.arange(n)
    keep: list[int] = []
    for i in range(n):
        earlier = torch.nonzero(close[i, :i] & (rep[:i] == torch.arange(i))).flatten()
        if earlier.numel():
            rep[i] = int(earlier[0])
        else:
            keep.append(i)
    keep_t = torch.tensor(keep, dtype=torch.long)
    new_index = torch.full((n,), -1, dtype=torch.long)
    new_index[keep_t] = torch.arange(len(keep))
    index_map = new_index[rep]
    rows = comparisons
    tie = torch.zeros(comparisons.shape[0], dtype=torch.bool)
    if ties is not None and ties.shape[0]:
        rows = torch.cat([comparisons, ties])
        tie = torch.cat([tie, torch.ones(ties.shape[0], dtype=torch.bool)])
    w = index_map[rows[:, 0]]
    l_ = index_map[rows[:, 1]]
    valid = w != l_
    if not valid.any():
        raise ValueError("comparisons contain no duel between distinct points (all self-duels)")
    return DuelData(
        X=X[keep_t].clone(),
        winners=w[valid],
        losers=l_[valid],
        index_map=index_map,
        tie=tie[valid],
    )
