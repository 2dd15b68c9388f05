"""The probit terms far in the tail (the hazard, the Hessian weight of eq. (8) and its slope)
against 120-digit references, and Newton's mode from a warm start far from the mode."""

from __future__ import annotations

import math

import mpmath
import pytest
import torch

from localpbo_core.surrogate.data import consolidate
from localpbo_core.surrogate.duel_space import dual_from_utilities, duel_covariance, find_mode
from localpbo_core.surrogate.kernel import se_kernel
from localpbo_core.surrogate.laplace import (
    WEIGHT_TAIL_Z,
    probit_hazard,
    probit_weight,
    probit_weight_slope,
)

Z = [-1e9, -1e6, -1e3, -100.0, -20.5, -20.0, -19.5, -14.5, -14.0, -13.5, -5.0, 0.0, 3.0, 30.0]


def _reference(z: float) -> tuple[float, float, float]:
    """Hazard h, weight c = 0.5 h (h + z) and dc/dz with 120 digits."""
    with mpmath.workdps(120):
        x = mpmath.mpf(z)
        h = mpmath.npdf(x) / mpmath.ncdf(x)
        c = h * (h + x) / 2
        slope = h * (1 - (x + h) * (x + 2 * h)) / 2
        return float(h), float(c), float(slope)


def _terms(z: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    h = probit_hazard(z, torch.special.log_ndtr(z))
    return h, probit_weight(z, h), probit_weight_slope(z, h)


def test_tail_terms_match_a_high_precision_reference() -> None:
    z = torch.tensor(Z, dtype=torch.float64)
    h, c, s = _terms(z)
    ref = torch.tensor([_reference(v) for v in Z], dtype=torch.float64)
    torch.testing.assert_close(h, ref[:, 0], rtol=1e-12, atol=0)
    torch.testing.assert_close(c, ref[:, 1], rtol=1e-11, atol=0)
    torch.testing.assert_close(s, ref[:, 2], rtol=1e-6, atol=0)
    assert torch.isfinite(torch.stack([h, c, s])).all()


def test_the_usual_range_keeps_the_plain_formulas_bit_for_bit() -> None:
    z = torch.linspace(WEIGHT_TAIL_Z, 40.0, 2001, dtype=torch.float64)
    log_cdf = torch.special.log_ndtr(z)
    plain = torch.exp(-0.5 * z * z - 0.5 * math.log(2.0 * math.pi) - log_cdf)
    h = probit_hazard(z, log_cdf)
    assert torch.equal(h, plain)
    assert torch.equal(probit_weight(z, h), 0.5 * h * (h + z))
    slope = 0.5 * h * (1.0 - (z + h) * (z + 2.0 * h))
    assert torch.equal(probit_weight_slope(z, h), slope)
    # one tail value in the batch does not change the others
    both = torch.cat([z, torch.tensor([-1e7], dtype=torch.float64)])
    h2 = probit_hazard(both, torch.special.log_ndtr(both))
    assert torch.equal(h2[:-1], h)


def test_gradients_stay_finite_in_the_tail() -> None:
    z = torch.tensor(Z, dtype=torch.float64, requires_grad=True)
    h, c, s = _terms(z)
    (h.sum() + c.sum() + s.sum()).backward()
    assert z.grad is not None and torch.isfinite(z.grad).all()


@pytest.mark.parametrize("outputscale", [1.0, 1.0e4])
def test_newton_reaches_the_mode_from_a_warm_start_far_from_it(duels, outputscale: float) -> None:
    X, comp = duels(4, 30, 5, scale=5.0)
    data = consolidate(X, comp)
    K = se_kernel(data.X, data.X, torch.full((4,), 0.3, dtype=torch.float64), outputscale)
    K = K + 1e-8 * outputscale * torch.eye(data.X.shape[0], dtype=torch.float64)
    M = duel_covariance(K, data.winners, data.losers)
    _, g_ref, _ = find_mode(M, torch.zeros(M.shape[0], dtype=torch.float64))
    # utilities that reverse every duel by about 300: with outputscale 1e4, g = M a0 ~ 1e8
    far = -300.0 * torch.sign(
        torch.zeros(data.X.shape[0], dtype=torch.float64).index_add(
            0, data.winners, torch.ones(data.winners.shape[0], dtype=torch.float64)
        )
    )
    a0 = dual_from_utilities(far, data.winners, data.losers)
    _, g, _ = find_mode(M, a0)
    assert torch.isfinite(g).all()
    torch.testing.assert_close(g, g_ref, rtol=0, atol=1e-6 * (1.0 + float(g_ref.abs().max())))
