"""Derivative-aware pairwise GP surrogate (paper Sec. 4)."""

from .pairwise_gp import PairwiseGPSurrogate

__all__ = ["PairwiseGPSurrogate"]
