"""GIPBO / GIPBOr (paper Sec. 5.1, App. C.2-C.3): the GI-PBO acquisition against brute-force
refits, the candidate set, the normalised step, budget accounting, determinism, progress."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from optim_helpers import drive, judged

from localpbo_core.optimizers import make_optimizer
from localpbo_core.optimizers.gi_acquisition import (
    gi_pbo_acquisition,
    hypersphere_candidates,
    random_local_query,
)
from localpbo_core.optimizers.gipbo import GIPBO, normalized_gradient_step
from localpbo_core.surrogate import PairwiseGPSurrogate
from localpbo_core.surrogate.virtual_refit import gradient_covariance_trace, virtual_refit

LS = torch.tensor([0.25, 0.35, 0.3], dtype=torch.float64)
OS = 2.0


def _data(n: int = 9, d: int = 3, seed: int = 0) -> tuple[torch.Tensor, torch.Tensor]:
    g = torch.Generator().manual_seed(seed)
    X = torch.rand(n, d, generator=g, dtype=torch.float64)
    y = -((X - 0.4) ** 2).sum(-1) + 0.05 * torch.randn(n, generator=g, dtype=torch.float64)
    comps = [[i, i - 1] if y[i] > y[i - 1] else [i - 1, i] for i in range(1, n)]
    return X, torch.tensor(comps)


def _trace(s: PairwiseGPSurrogate, x: torch.Tensor) -> float:
    return float(torch.diagonal(s.gradient_covariance(x)).sum())


def _brute(X, comps, center, cand, opp, threshold=0.0, outputscale=OS) -> float:
    """Eq. (16) "GIPBO acquisition" by two independent full fits (fixed hyperparameters)."""
    base = PairwiseGPSurrogate.fit(X, comps, lengthscale=LS, outputscale=outputscale)
    p_x = float(base.preference_probability(cand, opp))
    n = X.shape[0]
    Xe = torch.cat([X, opp[None], cand[None]])
    branches = []
    for prob, duel in ((p_x, [n + 1, n]), (1.0 - p_x, [n, n + 1])):
        if prob < threshold:
            continue
        fit = PairwiseGPSurrogate.fit(
            Xe, torch.cat([comps, torch.tensor([duel])]), lengthscale=LS, outputscale=outputscale
        )
        branches.append((prob, _trace(fit, center)))
    total = sum(p for p, _ in branches)
    return _trace(base, center) - sum(p / total * t for p, t in branches)


@pytest.mark.parametrize(
    ("opponent", "outputscale", "n"), [("data", OS, 9), ("new", OS, 9), ("new", 60.0, 14)]
)
def test_acquisition_equals_brute_force(opponent: str, outputscale: float, n: int) -> None:
    # a large outputscale makes the virtual duel move the MAP a lot (exercises the switch
    # from the chord phase to exact Newton in virtual_refit)
    X, comps = _data(n=n)
    s = PairwiseGPSurrogate.fit(X, comps, lengthscale=LS, outputscale=outputscale)
    center = X[4]
    g = torch.Generator().manual_seed(1)
    cands = (center + 0.15 * torch.randn(6, 3, generator=g, dtype=torch.float64)).clamp(0, 1)
    opp = X[4] if opponent == "data" else torch.tensor([0.6, 0.2, 0.5], dtype=torch.float64)
    acq = gi_pbo_acquisition(s, center, cands, opp)
    ref = torch.tensor(
        [_brute(X, comps, center, c, opp, outputscale=outputscale) for c in cands],
        dtype=torch.float64,
    )
    assert torch.allclose(acq, ref, atol=1e-7 * outputscale, rtol=0)
    assert (ref.abs() > 1e-4).all()  # the comparison is not vacuous


def test_likelihood_threshold_drops_unlikely_branch() -> None:
    X, comps = _data()
    s = PairwiseGPSurrogate.fit(X, comps, lengthscale=LS, outputscale=OS)
    center, opp = X[4], X[4]
    cands = torch.stack([X[1] * 0.5 + center * 0.5, torch.full((3,), 0.4, dtype=torch.float64)])
    probs = s.preference_probability(cands, opp.expand(2, 3))
    thr = float(torch.min(torch.minimum(probs, 1 - probs))) + 1e-3  # drops >= 1 branch
    acq = gi_pbo_acquisition(s, center, cands, opp, likelihood_threshold=thr)
    ref = torch.tensor([_brute(X, comps, center, c, opp, thr) for c in cands])
    assert torch.allclose(acq, ref.to(torch.float64), atol=1e-7, rtol=0)
    with pytest.raises(ValueError, match="likelihood_threshold"):
        gi_pbo_acquisition(s, center, cands, opp, likelihood_threshold=0.5)


def test_virtual_refit_map_equals_full_fit() -> None:
    X, comps = _data()
    s = PairwiseGPSurrogate.fit(X, comps, lengthscale=LS, outputscale=OS)
    z = torch.tensor([[[0.9, 0.1, 0.3]], [[0.2, 0.8, 0.6]]], dtype=torch.float64)
    fit = virtual_refit(s, z, torch.tensor([9, 2]), torch.tensor([0, 9]))
    traces = gradient_covariance_trace(s, fit, X[0])
    for b, duel in enumerate(([9, 0], [2, 9])):
        full = PairwiseGPSurrogate.fit(
            torch.cat([X, z[b]]),
            torch.cat([comps, torch.tensor([duel])]),
            lengthscale=LS,
            outputscale=OS,
        )
        assert abs(float(traces[b]) - _trace(full, X[0])) < 1e-8
        # f_hat = K H^T alpha: the MAP utilities agree with the full fit
        Ke = full.chol_K @ full.chol_K.T
        H = torch.zeros(comps.shape[0] + 1, 10, dtype=torch.float64)
        allc = torch.cat([comps, torch.tensor([duel])])
        H[torch.arange(allc.shape[0]), allc[:, 0]] = 1.0
        H[torch.arange(allc.shape[0]), allc[:, 1]] = -1.0
        f = Ke @ H.T @ fit.alpha[b]
        assert torch.allclose(f, full.utility, atol=1e-7)


def test_chosen_query_reduces_gradient_uncertainty_for_both_outcomes() -> None:
    X, comps = _data(seed=3)
    s = PairwiseGPSurrogate.fit(X, comps, lengthscale=LS, outputscale=OS)
    center = X[5]
    cands = torch.tensor(
        hypersphere_candidates(center.numpy(), np.random.default_rng(0)), dtype=torch.float64
    )
    acq = gi_pbo_acquisition(s, center, cands, center)
    best = cands[int(torch.argmax(acq))]
    before = _trace(s, center)
    for duel in ([9, 5], [5, 9]):
        fit = PairwiseGPSurrogate.fit(
            torch.cat([X, best[None]]),
            torch.cat([comps, torch.tensor([duel])]),
            lengthscale=LS,
            outputscale=OS,
        )
        assert _trace(fit, center) < before
    assert float(acq.max()) > float(torch.median(acq[torch.isfinite(acq)]))


def test_candidate_set_sizes_radii_and_projection() -> None:
    rng = np.random.default_rng(0)
    c6 = np.full(6, 0.5)
    pts = hypersphere_candidates(c6, rng)
    assert pts.shape == (300, 6)  # 50 d
    r = np.linalg.norm(pts - c6, axis=1)
    for k, rad in enumerate((0.05, 0.1, 0.15, 0.2)):
        assert np.allclose(r[75 * k : 75 * (k + 1)], rad)
    assert hypersphere_candidates(np.full(16, 0.5), rng).shape == (512, 16)  # cap
    pts2 = hypersphere_candidates(np.array([0.5, 0.5]), rng)
    r2 = np.linalg.norm(pts2 - 0.5, axis=1)
    assert pts2.shape == (2500, 2) and np.allclose(
        np.unique(r2.round(9)), np.linspace(0.05, 0.2, 10)
    )
    corner = hypersphere_candidates(np.zeros(6), rng)
    assert corner.min() >= 0.0 and corner.max() <= 1.0
    q = [random_local_query(c6, rng) for _ in range(200)]
    rq = np.linalg.norm(np.array(q) - c6, axis=1)
    assert rq.min() >= 0.05 and rq.max() <= 0.2


def test_normalized_gradient_step() -> None:
    ls = np.array([0.1, 0.4, 0.2])
    g = np.array([1.0, -2.0, 0.5])
    step = normalized_gradient_step(g, ls, 0.5, 0.0)
    assert np.isclose(np.sqrt(np.sum(step**2 / ls**2)), 0.5)  # unit Mahalanobis norm times eta
    assert np.allclose(step / np.linalg.norm(step), g / np.linalg.norm(g))
    small = normalized_gradient_step(g, np.full(3, 0.05), 0.5, 0.05)
    assert np.isclose(np.linalg.norm(small), 0.05)
    assert not normalized_gradient_step(np.zeros(3), ls, 0.5, 0.05).any()


C2 = np.array([0.75, 0.25])
C6 = np.array([0.3, 0.7, 0.4, 0.6, 0.25, 0.5])


def _quad2(theta: np.ndarray) -> float:
    return float(-np.sum((np.asarray(theta) - C2) ** 2))


def _quad6(theta: np.ndarray) -> float:
    return float(-np.sum((np.asarray(theta) - C6) ** 2))


def closed_gap(alg: str, dim: int, seed: int, budget: int) -> float:
    """Fraction of the gap between the initial best and the optimum (0) closed by the run
    (noise-free preferences on a smooth concave utility)."""
    judge = _quad2 if dim == 2 else _quad6
    vals = np.array([judge(t) for t in drive(make_optimizer(alg, dim, seed, budget), judge)])
    return float((vals.max() - vals[:2].max()) / -vals[:2].max())


@pytest.mark.parametrize(("alg", "seeds"), [("gipbo", (0, 1)), ("gipbor", (0, 1, 2))])
def test_improves_on_smooth_2d(alg: str, seeds: tuple[int, ...]) -> None:
    for seed in seeds:
        assert closed_gap(alg, 2, seed, 22) > 0.8, seed


@pytest.mark.parametrize(
    ("alg", "seeds", "budget"), [("gipbo", (0, 1), 26), ("gipbor", (0, 1, 2), 62)]
)
def test_improves_on_smooth_6d(alg: str, seeds: tuple[int, ...], budget: int) -> None:
    for seed in seeds:
        assert closed_gap(alg, 6, seed, budget) > 0.6, seed


def _accounting(opt: GIPBO) -> tuple[int, int]:
    comps = 0
    vals: dict[int, float] = {}
    while not opt.done:
        ask = opt.ask()
        for c in ask.candidates:
            vals[c.id] = _quad2(c.theta)
        if len(ask.candidates) == 2 and not opt.in_initial_design:
            center, query = ask.candidates
            # the new center is evaluated now and is the opponent of the first local query
            assert ask.duels == (type(ask.duels[0])(query.id, center.id),)
        comps += len(ask.duels)
        opt.tell(judged(vals, ask.duels))
    return comps, len(vals)


def test_budget_and_comparison_accounting() -> None:
    # d = 2: 2 initial + 2 queries, then phases of 1 center + 2 queries (App. D.1)
    opt = make_optimizer("gipbor", 2, seed=0, budget=22)
    comps, n = _accounting(opt)
    assert n == 22 and opt.gradient_steps == 6 and comps == n - 1 - opt.gradient_steps
    # a step center that would be the last evaluation is dueled against the incumbent
    opt = make_optimizer("gipbor", 2, seed=0, budget=8)
    comps, n = _accounting(opt)
    assert n == 8 and opt.gradient_steps == 2 and comps == n - opt.gradient_steps


@pytest.mark.parametrize("alg", ["gipbo", "gipbor"])
def test_determinism(alg: str) -> None:
    runs = [drive(make_optimizer(alg, 3, seed=s, budget=14)) for s in (5, 5, 6)]
    assert all(np.array_equal(a, b) for a, b in zip(runs[0], runs[1], strict=True))
    assert not all(np.array_equal(a, b) for a, b in zip(runs[0], runs[2], strict=True))


def test_validation_names_the_field() -> None:
    for kw, field in (
        ({"step_size": 0.0}, "step_size"),
        ({"num_local_queries": 0}, "num_local_queries"),
        ({"search_bounds": (0.3, 0.1)}, "search_bounds"),
        ({"radii": ()}, "radii"),
        ({"likelihood_threshold": 0.7}, "likelihood_threshold"),
        ({"virtual_opponent": "x"}, "virtual_opponent"),
        ({"resolution": 0}, "resolution"),
    ):
        with pytest.raises(ValueError, match=field):
            make_optimizer("gipbo", 3, **kw)
    with pytest.raises(ValueError, match="likelihood_threshold"):
        make_optimizer("gipbor", 3, likelihood_threshold=0.1)  # not an option of GIPBOr


def test_virtual_opponent_accepts_both_spellings_of_center() -> None:
    for value in ("center", "centre"):
        opt = make_optimizer("gipbo", 2, seed=3, budget=9, virtual_opponent=value)
        assert isinstance(opt, GIPBO) and opt.virtual_opponent == "center"


def test_virtual_refit_rejects_unsupported_fits() -> None:
    X, comps = _data()
    z = torch.tensor([[[0.9, 0.1, 0.3]]], dtype=torch.float64)
    clamped = PairwiseGPSurrogate.fit(X, comps, lengthscale=LS, outputscale=OS, z_limit=3.0)
    with pytest.raises(ValueError, match="z_limit"):
        virtual_refit(clamped, z, torch.tensor([9]), torch.tensor([0]))
    s = PairwiseGPSurrogate.fit(X, comps, lengthscale=LS, outputscale=OS)
    with pytest.raises(ValueError, match="distinct"):
        virtual_refit(s, z, torch.tensor([9]), torch.tensor([9]))
