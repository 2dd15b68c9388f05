"""Ordinal probit likelihood with an indifference threshold: "can't tell" answers.

The paper's likelihood (Sec. 4, eq. (5) "likelihood", BoTorch's sigma_n = 1) of a decisive duel
with utility difference ``g = f(first) - f(second)`` is ``Phi(g / sqrt(2))``. A judge who may
also answer "can't tell" is modelled as in ordinal regression with three ordered classes
(Chu & Ghahramani 2005, "Gaussian processes for ordinal regression", JMLR 6, Sec. 2.1): the
noisy difference ``g + n``, ``n ~ N(0, 2)`` (the two observation noises of paper eq. (2)),
is compared with the threshold ``eps >= 0`` (``tie_threshold``, in latent-utility units):

    ``P(first > second | g) = Phi((g - eps) / sqrt(2))``,
    ``P(tie | g) = Phi((eps - g) / sqrt(2)) - Phi((-eps - g) / sqrt(2))``.

``eps = 0`` is exactly the paper's likelihood (and leaves no probability to a tie). Both
log-likelihoods are concave in ``g`` (a Gaussian CDF and a Gaussian interval probability are
log-concave in the location), so the Laplace/Newton machinery of :mod:`.laplace` stays valid
with the per-duel weights ``c = -d^2 log p / dg^2 >= 0`` replacing eq. (8)'s.

For a tie write ``a = (eps - g) / sqrt(2)``, ``b = (-eps - g) / sqrt(2)``,
``Z = Phi(a) - Phi(b)``, ``r_a = phi(a) / Z``, ``r_b = phi(b) / Z``. With ``D`` the derivative
under a common shift of ``a`` and ``b`` (``d/dg = -D / sqrt(2)``):

    ``D log Z = r_a - r_b =: L1``,
    ``D^2 log Z = -(a r_a - b r_b) - L1^2 =: L2``,
    ``D^3 log Z = -(1 - a^2) r_a + (1 - b^2) r_b + (a r_a - b r_b) L1 - 2 L1 L2 =: L3``,

so ``dlog p/dg = -L1 / sqrt(2)``, ``c = -L2 / 2`` and ``dc/dg = L3 / (2 sqrt(2))``. ``log Z`` is
evaluated as a log-difference of normal CDFs, ``log Phi(a) + log(1 - exp(log Phi(b) -
log Phi(a)))`` with ``torch.special.log_ndtr``, at ``|g|`` (the interval then lies on the
lower side of the Gaussian, where ``log_ndtr`` keeps full relative accuracy); the tie
likelihood is even in ``g``, so its odd derivatives take the sign of ``g``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import torch
from torch import Tensor

SQRT2 = math.sqrt(2.0)
_LOG_SQRT_2PI = 0.5 * math.log(2.0 * math.pi)


@dataclass(frozen=True)
class Ordinal:
    """Which duels are ties (``tie`` ``(m,)`` bool, aligned with the duel rows) and the
    indifference threshold ``threshold`` (``eps >= 0``). Tie rows read ``winners[n]`` /
    ``losers[n]`` as first / second (the tie likelihood is symmetric)."""

    tie: Tensor
    threshold: float

    def __post_init__(self) -> None:
        if not math.isfinite(self.threshold) or self.threshold < 0:
            raise ValueError(f"tie_threshold must be finite and >= 0, got {self.threshold}")
        if self.threshold == 0 and bool(self.tie.any()):
            raise ValueError("ties need tie_threshold > 0 (a tie has probability 0 at eps = 0)")

    @property
    def is_plain(self) -> bool:
        """True when this is the paper's probit exactly (no tie and ``eps = 0``)."""
        return self.threshold == 0 and not bool(self.tie.any())


def _log_normal_pdf(x: Tensor) -> Tensor:
    return -0.5 * x * x - _LOG_SQRT_2PI


def log1mexp(x: Tensor) -> Tensor:
    """``log(1 - exp(x))`` for ``x <= 0``, accurate near 0 and for very negative ``x``."""
    return torch.where(x > -math.log(2.0), torch.log(-torch.expm1(x)), torch.log1p(-torch.exp(x)))


def log_interval_probability(a: Tensor, b: Tensor) -> Tensor:
    """``log(Phi(a) - Phi(b))`` for ``a > b`` with the interval not above 0 in its centre
    (``a + b <= 0``); see the module docstring."""
    la = torch.special.log_ndtr(a)
    return la + log1mexp(torch.special.log_ndtr(b) - la)


@dataclass(frozen=True)
class TieTerms:
    """Per-tie ``log p``, ``dlog p / dg``, ``c = -d^2 log p / dg^2`` and ``dc/dg``."""

    log_lik: Tensor
    d1: Tensor
    weight: Tensor
    weight_slope: Tensor


def tie_terms(g: Tensor, threshold: float) -> TieTerms:
    """The tie likelihood ``Phi((eps - g)/sqrt 2) - Phi((-eps - g)/sqrt 2)`` and its derivatives
    in ``g`` (module docstring). Differentiable (autograd) in ``g``."""
    if threshold <= 0:
        raise ValueError("tie_terms: the threshold must be > 0")
    sign = torch.where(g < 0, -torch.ones_like(g), torch.ones_like(g))
    ga = g.abs()
    a = (threshold - ga) / SQRT2
    b = (-threshold - ga) / SQRT2
    log_z = log_interval_probability(a, b)
    ra = torch.exp(_log_normal_pdf(a) - log_z)
    rb = torch.exp(_log_normal_pdf(b) - log_z)
    L1 = ra - rb
    m1 = a * ra - b * rb
    L2 = -m1 - L1 * L1
    L3 = -(1.0 - a * a) * ra + (1.0 - b * b) * rb + m1 * L1 - 2.0 * L1 * L2
    return TieTerms(
        log_lik=log_z,
        d1=-sign * L1 / SQRT2,
        weight=-0.5 * L2,
        weight_slope=sign * L3 / (2.0 * SQRT2),
    )


def tie_log_likelihood(g: Tensor, threshold: float) -> Tensor:
    """``log P(tie | g)`` only (cheaper than :func:`tie_terms`)."""
    ga = g.abs()
    return log_interval_probability((threshold - ga) / SQRT2, (-threshold - ga) / SQRT2)


def preference_log_likelihood(g: Tensor, threshold: float) -> Tensor:
    """``log P(first > second | g) = log Phi((g - eps) / sqrt(2))``."""
    return torch.special.log_ndtr((g - threshold) / SQRT2)


def duel_log_likelihood(g: Tensor, tie: Tensor, threshold: float) -> Tensor:
    """Per-duel ``log p`` of the ordinal model (decisive rows: winner first)."""
    dec = preference_log_likelihood(g, threshold)
    if not bool(tie.any()):
        return dec
    return torch.where(tie, tie_log_likelihood(g, threshold), dec)
