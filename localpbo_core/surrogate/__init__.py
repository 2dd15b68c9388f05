"""Derivative-aware pairwise GP surrogate (paper Sec. 4) and the contract it implements."""

from .pairwise_gp import PairwiseGPSurrogate
from .protocol import Surrogate

__all__ = ["PairwiseGPSurrogate", "Surrogate"]
