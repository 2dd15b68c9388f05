"""qEUBO baseline: the BoTorch adapter against ``posterior_mean_cov`` and BoTorch's own
``PairwiseGP``, closed-form EUBO, the q > 1 bracket protocol, budget, determinism, options."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch
from botorch.acquisition.preference import (
    AnalyticExpectedUtilityOfBestOption,
    qExpectedUtilityOfBestOption,
)
from botorch.models import PairwiseGP
from botorch.sampling import SobolQMCNormalSampler
from gpytorch.kernels import RBFKernel, ScaleKernel
from optim_helpers import drive, utility

from localpbo_core.optimizers import Outcome, make_optimizer
from localpbo_core.optimizers.botorch_adapter import SurrogateModel, batched_mean_cov
from localpbo_core.optimizers.qeubo import QEUBO
from localpbo_core.surrogate import PairwiseGPSurrogate

pytestmark = pytest.mark.usefixtures("one_torch_thread")


def _duels(d: int, n: int, seed: int) -> tuple[torch.Tensor, torch.Tensor]:
    """``n`` king-of-the-hill style duels on ``n + 1`` random points of a smooth utility."""
    g = torch.Generator().manual_seed(seed)
    X = torch.rand(n + 1, d, generator=g, dtype=torch.float64)
    y = -((X - 0.4) ** 2).sum(-1) * 4.0 + 0.3 * torch.sin(5.0 * X.sum(-1))
    new = torch.arange(1, n + 1)
    old = (torch.rand(n, generator=g, dtype=torch.float64) * new).long()
    win = y[new] > y[old]
    comp = torch.stack([torch.where(win, new, old), torch.where(win, old, new)], dim=1)
    return X, comp


def _phi(u: float) -> float:
    return math.exp(-0.5 * u * u) / math.sqrt(2.0 * math.pi)


def _cdf(u: float) -> float:
    return 0.5 * (1.0 + math.erf(u / math.sqrt(2.0)))


def _eubo_closed_form(m: torch.Tensor, c: torch.Tensor) -> float:
    """``E[max(f0, f1)] - m1`` for a bivariate normal (Lin et al. 2022, analytic EUBO)."""
    s = math.sqrt(float(c[0, 0] + c[1, 1] - 2.0 * c[0, 1]))
    u = float(m[0] - m[1]) / s
    return s * (_phi(u) + u * _cdf(u))


@pytest.fixture(scope="module")
def fitted() -> PairwiseGPSurrogate:
    X, comp = _duels(3, 25, 0)
    return PairwiseGPSurrogate.fit(X, comp)


@pytest.mark.parametrize("eps_reg", [0.0, 1e-2])
def test_batched_posterior_equals_posterior_mean_cov(fitted, eps_reg):
    if eps_reg:
        X, comp = _duels(3, 25, 0)
        fitted = PairwiseGPSurrogate.fit(X, comp, eps_reg=eps_reg)
    g = torch.Generator().manual_seed(1)
    Xb = torch.rand(7, 3, 3, generator=g, dtype=torch.float64)
    mean, cov = batched_mean_cov(fitted, Xb)
    post = SurrogateModel(fitted).posterior(Xb.reshape(7, 1, 3, 3))
    for b in range(7):
        m_ref, c_ref = fitted.posterior_mean_cov(Xb[b])
        torch.testing.assert_close(mean[b], m_ref, rtol=1e-10, atol=1e-12)
        torch.testing.assert_close(cov[b], c_ref, rtol=1e-10, atol=1e-12)
        torch.testing.assert_close(post.mean[b, 0, :, 0], m_ref, rtol=1e-10, atol=1e-12)
        torch.testing.assert_close(post.covariance_matrix[b, 0], c_ref, rtol=1e-9, atol=1e-12)


def test_adapter_gradients_match_finite_differences(fitted):
    x = torch.tensor([[[0.2, 0.7, 0.4]]], dtype=torch.float64, requires_grad=True)
    w = torch.tensor([[0.5, 0.5, 0.5]], dtype=torch.float64)
    acq = AnalyticExpectedUtilityOfBestOption(SurrogateModel(fitted), previous_winner=w)
    (grad,) = torch.autograd.grad(acq(x).sum(), x)
    h = 1e-6
    for i in range(3):
        e = torch.zeros_like(x)
        e[..., i] = h
        with torch.no_grad():
            fd = (acq(x + e) - acq(x - e)).item() / (2 * h)
        assert abs(fd - grad[0, 0, i].item()) < 1e-6 * (1 + abs(fd))


def test_analytic_eubo_on_adapter_equals_closed_form(fitted):
    g = torch.Generator().manual_seed(2)
    X = torch.rand(6, 1, 3, generator=g, dtype=torch.float64)
    w = torch.tensor([[0.45, 0.35, 0.5]], dtype=torch.float64)
    acq = AnalyticExpectedUtilityOfBestOption(SurrogateModel(fitted), previous_winner=w)
    vals = acq(X)
    for i in range(6):
        m, c = fitted.posterior_mean_cov(torch.cat([X[i], w]))
        assert abs(vals[i].item() - _eubo_closed_form(m, c)) < 1e-10


def test_qeubo_on_adapter_equals_direct_monte_carlo(fitted):
    g = torch.Generator().manual_seed(3)
    X = torch.rand(4, 2, 3, generator=g, dtype=torch.float64)
    sampler = SobolQMCNormalSampler(torch.Size([4096]), seed=5)
    acq = qExpectedUtilityOfBestOption(SurrogateModel(fitted), sampler=sampler)
    vals = acq(X)
    base = sampler.base_samples.reshape(4096, 2)  # (S, q) standard normal draws
    for i in range(4):
        m, c = fitted.posterior_mean_cov(X[i])
        direct = (m + base @ torch.linalg.cholesky(c).T).max(-1).values.mean()
        assert abs(vals[i].item() - direct.item()) < 1e-8
        # and the QMC estimate is close to the closed form E[max(f1, f2)]
        exact = _eubo_closed_form(m, c) + m[1].item()
        assert abs(vals[i].item() - exact) < 5e-3 * math.sqrt(c[0, 0].item() + c[1, 1].item())


def test_eubo_matches_botorch_pairwise_gp_with_fixed_hyperparameters():
    d = 3
    X, comp = _duels(d, 20, 4)
    ls = torch.tensor([0.3, 0.25, 0.4], dtype=torch.float64)
    os_ = 2.0
    ours = PairwiseGPSurrogate.fit(X, comp, ls, os_, z_limit=3.0, jitter=0.0)
    base = RBFKernel(ard_num_dims=d)
    kern = ScaleKernel(base).to(torch.float64)
    base.lengthscale = ls.reshape(1, d)
    kern.outputscale = torch.tensor(os_, dtype=torch.float64)
    ref = PairwiseGP(X, comp, covar_module=kern, xtol=1e-12)
    ref.eval()
    torch.testing.assert_close(ours.utility, ref.utility, rtol=1e-7, atol=1e-8)
    g = torch.Generator().manual_seed(6)
    Xq = torch.rand(8, 1, d, generator=g, dtype=torch.float64)
    w = X[int(comp[-1, 0])].reshape(1, d)
    mine = AnalyticExpectedUtilityOfBestOption(SurrogateModel(ours), previous_winner=w)(Xq)
    theirs = AnalyticExpectedUtilityOfBestOption(ref, previous_winner=w)(Xq)
    torch.testing.assert_close(mine, theirs, rtol=1e-6, atol=1e-8)


def _values(opt: QEUBO) -> np.ndarray:
    return np.array([utility(c.theta) for c in opt.history.candidates])


@pytest.mark.parametrize("q", [1, 2, 4])
def test_budget_accounting_and_incumbent(q):
    opt = QEUBO(dim=2, seed=0, budget=22, batch_size=q, num_raw_samples=256)
    drive(opt)
    hist = opt.history
    assert len(hist.candidates) == 22
    assert len(hist.duels) == 21  # App. D.1: 2 + 10d evaluations -> 1 + 10d comparisons
    assert len(hist.outcomes) == 21
    # noise-free transitive preferences: the king of the hill is the best evaluated point
    assert opt.incumbent.id == int(np.argmax(_values(opt)))


def test_bracket_duels_new_points_among_themselves_then_incumbent():
    opt = QEUBO(dim=2, seed=1, budget=6, batch_size=4, num_raw_samples=128)
    values: dict[int, float] = {}

    def answer(ask):
        for c in ask.candidates:
            values[c.id] = utility(c.theta)
        return [
            Outcome(x.first, x.second)
            if values[x.first] >= values[x.second]
            else Outcome(x.second, x.first)
            for x in ask.duels
        ]

    a = opt.ask()  # initial design: 2 evaluations, 1 duel
    opt.tell(answer(a))
    inc = opt.incumbent.id
    a = opt.ask()  # round 1: (2, 3), (4, 5)
    assert [c.id for c in a.candidates] == [2, 3, 4, 5]
    assert [(x.first, x.second) for x in a.duels] == [(2, 3), (4, 5)]
    opt.tell(answer(a))
    assert not opt.done
    a = opt.ask()  # round 2: the two winners
    w1 = 2 if values[2] >= values[3] else 3
    w2 = 4 if values[4] >= values[5] else 5
    assert a.candidates == () and [(x.first, x.second) for x in a.duels] == [(w1, w2)]
    opt.tell(answer(a))
    a = opt.ask()  # final: bracket winner against the incumbent
    best = w1 if values[w1] >= values[w2] else w2
    assert a.candidates == () and [(x.first, x.second) for x in a.duels] == [(best, inc)]
    opt.tell(answer(a))
    assert opt.done
    assert len(opt.history.duels) == 5  # 6 evaluations -> 5 comparisons
    assert opt.incumbent.id == max(values, key=values.get)


def test_deterministic_per_seed():
    runs = [
        np.stack(drive(QEUBO(dim=2, seed=s, budget=8, batch_size=2, num_raw_samples=128)))
        for s in (3, 3, 4)
    ]
    np.testing.assert_array_equal(runs[0], runs[1])
    assert not np.array_equal(runs[0], runs[2])


def test_improves_on_smooth_2d_problem():
    opt = make_optimizer("qeubo", dim=2, seed=0, budget=22)
    thetas = drive(opt)
    vals = np.array([utility(t) for t in thetas])
    assert vals[2:].max() > vals[:2].max()
    assert utility(opt.incumbent.theta) > -0.01  # optimum 0 at (0.3, 0.3)


@pytest.mark.parametrize(
    ("options", "field"),
    [
        ({"batch_size": 0}, "batch_size"),
        ({"num_restarts": 0}, "num_restarts"),
        ({"num_raw_samples": 2, "num_restarts": 5}, "num_restarts"),
        ({"num_mc_samples": 1.5}, "num_mc_samples"),
        ({"hyperparameter_refit_every": 0}, "hyperparameter_refit_every"),
        ({"acquisition": "ts"}, "acquisition"),
    ],
)
def test_bad_options_raise(options, field):
    with pytest.raises(ValueError, match=field):
        make_optimizer("qeubo", dim=2, seed=0, **options)


def test_adapter_rejects_bad_input(fitted):
    model = SurrogateModel(fitted)
    with pytest.raises(ValueError, match="observation_noise"):
        model.posterior(torch.rand(1, 3, dtype=torch.float64), observation_noise=True)
    with pytest.raises(ValueError, match="X"):
        batched_mean_cov(fitted, torch.rand(2, 3, dtype=torch.float64))
