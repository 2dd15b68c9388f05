"""The ordinal probit of "can't tell" answers: derivatives, Laplace evidence and its gradient."""

from __future__ import annotations

import math

import pytest
import torch

from localpbo_core.surrogate import PairwiseGPSurrogate
from localpbo_core.surrogate.data import consolidate
from localpbo_core.surrogate.hyperparameters import evaluate, evaluate_with_gradient
from localpbo_core.surrogate.laplace import probit_terms_of_differences
from localpbo_core.surrogate.ordinal import Ordinal, tie_terms

G = torch.tensor([-30.0, -7.0, -1.3, -0.2, 0.0, 0.4, 1.1, 5.0, 30.0], dtype=torch.float64)


def _direct_tie(g: torch.Tensor, eps: float) -> torch.Tensor:
    s = math.sqrt(2.0)
    return torch.log(torch.special.ndtr((eps - g) / s) - torch.special.ndtr((-eps - g) / s))


@pytest.mark.parametrize("eps", [0.1, 0.5, 2.0])
def test_tie_derivatives_match_high_precision(eps: float) -> None:
    """Against 150-digit arithmetic (mpmath), including g = +-30 where float64 autograd of the
    direct formula loses its digits."""
    mp = pytest.importorskip("mpmath")
    mp.mp.dps = 150

    def ll(x: object) -> object:
        # Phi(a) - Phi(b) with Phi(y) = erfc(-y / sqrt 2) / 2, exact in the tails
        return mp.log((mp.erfc((x - eps) / 2) - mp.erfc((x + eps) / 2)) / 2)

    t = tie_terms(G, eps)
    for i, gv in enumerate(G.tolist()):
        x = mp.mpf(gv)
        assert float(t.log_lik[i]) == pytest.approx(float(ll(x)), rel=1e-12)
        assert float(t.d1[i]) == pytest.approx(float(mp.diff(ll, x)), rel=1e-9, abs=1e-12)
        assert float(t.weight[i]) == pytest.approx(float(-mp.diff(ll, x, 2)), rel=1e-9)
        assert float(t.weight_slope[i]) == pytest.approx(
            float(-mp.diff(ll, x, 3)), rel=1e-5, abs=1e-11
        )


@pytest.mark.parametrize("eps", [0.5, 2.0])
def test_tie_derivatives_match_autograd(eps: float) -> None:
    g = G[(G.abs() <= 2) & (G != 0)].clone().requires_grad_(True)  # autograd of |g| at 0 is 0
    t = tie_terms(g, eps)
    d1 = torch.autograd.grad(t.log_lik.sum(), g, create_graph=True)[0]
    d2 = torch.autograd.grad(d1.sum(), g, create_graph=True)[0]
    d3 = torch.autograd.grad(d2.sum(), g)[0]
    assert torch.allclose(t.d1, d1, rtol=1e-7, atol=1e-9)
    assert torch.allclose(t.weight, -d2, rtol=1e-6, atol=1e-8)
    assert torch.allclose(t.weight_slope, -d3, rtol=1e-5, atol=1e-7)
    assert torch.isfinite(t.log_lik).all() and (t.weight > 0).all()
    # the value against the direct formula where that is accurate (|g| small)
    assert torch.allclose(t.log_lik, _direct_tie(g.detach(), eps), rtol=1e-12)


def test_tie_derivatives_match_finite_differences() -> None:
    eps, h = 0.7, 1e-5
    g = torch.tensor([-30.0, -2.0, 0.3, 30.0], dtype=torch.float64)
    t, tp, tm = tie_terms(g, eps), tie_terms(g + h, eps), tie_terms(g - h, eps)
    assert torch.allclose(t.d1, (tp.log_lik - tm.log_lik) / (2 * h), rtol=1e-6, atol=1e-6)
    assert torch.allclose(t.weight, -(tp.d1 - tm.d1) / (2 * h), rtol=1e-6, atol=1e-6)
    assert torch.allclose(t.weight_slope, (tp.weight - tm.weight) / (2 * h), rtol=1e-5, atol=1e-6)


def test_decisive_with_threshold_matches_autograd() -> None:
    eps = 0.6
    g = G.clone().requires_grad_(True)
    tie = torch.tensor([False, True, False, True, False, True, False, True, False])
    t = probit_terms_of_differences(g, None, Ordinal(tie, eps))
    direct = torch.where(
        tie, tie_terms(g, eps).log_lik, torch.special.log_ndtr((g - eps) / math.sqrt(2.0))
    )
    assert torch.allclose(t.log_cdf, direct, rtol=1e-12)
    d1 = torch.autograd.grad(direct.sum(), g, create_graph=True)[0]
    d2 = torch.autograd.grad(d1.sum(), g, create_graph=True)[0]
    d3 = torch.autograd.grad(d2.sum(), g)[0]
    assert t.weight is not None and t.weight_slope is not None
    assert torch.allclose(t.hazard / math.sqrt(2.0), d1, rtol=1e-7, atol=1e-9)
    assert torch.allclose(t.weight, -d2, rtol=1e-6, atol=1e-8)
    assert torch.allclose(t.weight_slope / math.sqrt(2.0), -d3, rtol=1e-5, atol=1e-7)


def _data(seed: int = 0) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    gen = torch.Generator().manual_seed(seed)
    X = torch.rand(14, 3, generator=gen, dtype=torch.float64)
    comps = torch.tensor([[0, 1], [2, 1], [3, 4], [5, 0], [6, 7], [8, 2], [9, 3]])
    ties = torch.tensor([[10, 11], [12, 13], [4, 6], [1, 9]])
    return X, comps, ties


@pytest.mark.parametrize("form", ["whitened", "duels"])
def test_evidence_gradient_with_ties_matches_autograd(form: str) -> None:
    X, comps, ties = _data()
    data = consolidate(X, comps, ties=ties)
    ordinal = Ordinal(data.tie, 0.5)
    ls = torch.tensor([0.3, 0.2, 0.4], dtype=torch.float64)
    os_ = 2.5
    f0 = torch.zeros(data.X.shape[0], dtype=torch.float64)
    if form == "duels":  # more points than duels is what the duel form is for
        assert data.winners.shape[0] <= data.X.shape[0]
    value, g_ls, g_os, _ = evaluate_with_gradient(
        data.X, data.winners, data.losers, ls, os_, f0, 1e-8, None, form=form, ordinal=ordinal
    )
    log_ls = ls.log().requires_grad_(True)
    log_os = torch.tensor(math.log(os_), dtype=torch.float64, requires_grad=True)
    ref, _, _ = evaluate(
        data.X,
        data.winners,
        data.losers,
        log_ls.exp(),
        log_os.exp(),
        f0,
        1e-8,
        None,
        ordinal=ordinal,
    )
    ref.backward()
    assert value == pytest.approx(float(ref), rel=1e-9)
    assert log_ls.grad is not None and log_os.grad is not None
    assert torch.allclose(g_ls, log_ls.grad, rtol=1e-6, atol=1e-8)
    assert float(g_os) == pytest.approx(float(log_os.grad), rel=1e-6, abs=1e-8)


def test_mode_with_ties_is_the_minimiser_of_the_direct_objective() -> None:
    X, comps, ties = _data(1)
    s = PairwiseGPSurrogate.fit(
        X, comps, ties=ties, tie_threshold=0.5, lengthscale=0.3, outputscale=2.0
    )
    f = s.utility.clone().requires_grad_(True)
    g = f[s.winners] - f[s.losers]
    eps, r2 = 0.5, math.sqrt(2.0)
    loglik = torch.where(s.tie, _direct_tie(g, eps), torch.special.log_ndtr((g - eps) / r2)).sum()
    K = s.chol_K @ s.chol_K.T
    S = -loglik + 0.5 * f @ torch.linalg.solve(K, f)
    (grad,) = torch.autograd.grad(S, f)
    assert grad.abs().max() < 1e-6
    # ties pull the two utilities together, decisive duels push them apart by more than eps
    assert s.tie.sum() == 4


def test_zero_threshold_without_ties_is_the_paper_model_bit_for_bit() -> None:
    X, comps, _ = _data(2)
    a = PairwiseGPSurrogate.fit(X, comps)
    b = PairwiseGPSurrogate.fit(
        X, comps, ties=torch.empty(0, 2, dtype=torch.long), tie_threshold=0.0
    )
    assert torch.equal(a.utility, b.utility) and torch.equal(a.lengthscale, b.lengthscale)
    assert a.ordinal is None and b.ordinal is None


def test_ties_only_fit_and_probabilities() -> None:
    X, _, ties = _data(3)
    s = PairwiseGPSurrogate.fit(
        X, torch.empty(0, 2, dtype=torch.long), ties=ties, tie_threshold=1.0
    )
    assert torch.isfinite(s.utility).all()
    x, y = X[10], X[11]
    total = (
        s.preference_probability(x, y) + s.preference_probability(y, x) + s.tie_probability(x, y)
    )
    assert float(total) == pytest.approx(1.0, abs=1e-12)
    with pytest.raises(ValueError, match="tie_threshold"):
        PairwiseGPSurrogate.fit(X, torch.empty(0, 2, dtype=torch.long), ties=ties)


def test_tie_between_merged_points_is_dropped() -> None:
    X = torch.tensor([[0.1, 0.1], [0.1 + 1e-6, 0.1], [0.8, 0.3]], dtype=torch.float64)
    data = consolidate(X, torch.tensor([[2, 0]]), ties=torch.tensor([[0, 1], [1, 2]]))
    assert data.tie.tolist() == [False, True]
    assert data.winners.tolist() == [1, 0] and data.losers.tolist() == [0, 1]
