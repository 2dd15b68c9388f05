"""``check_seed`` for :mod:`.oracle`; every other check lives in :mod:`localpbo_core.validation`."""

from __future__ import annotations

from localpbo_core.validation import check_int


def check_seed(seed: int) -> int:
    """``check_int("seed", seed, minimum=0)``: the seed as a non-negative Python int."""
    return check_int("seed", seed, minimum=0)
