"""Input checks shared by the problems: errors name the offending field (``theta``, ``seed``)."""

from __future__ import annotations

import numpy as np


def check_theta(theta: np.ndarray, dim: int, problem: str) -> np.ndarray:
    """Return theta as a float64 vector of shape (dim,) in [0,1]^d, or raise ValueError."""
    arr = np.asarray(theta, dtype=np.float64)
    if arr.shape != (dim,):
        raise ValueError(f"theta: expected shape ({dim},) for {problem}, got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"theta: contains NaN or inf for {problem}")
    if np.any(arr < 0.0) or np.any(arr > 1.0):
        raise ValueError(f"theta: entries must lie in [0, 1] for {problem}")
    return arr


def check_seed(seed: int) -> int:
    """Return seed as a non-negative Python int, or raise ValueError."""
    if isinstance(seed, bool) or not isinstance(seed, int | np.integer) or seed < 0:
        raise ValueError(f"seed: expected a non-negative integer, got {seed!r}")
    return int(seed)
