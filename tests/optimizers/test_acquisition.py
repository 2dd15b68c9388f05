"""(q)EUBO and Thompson-sampling optimisation inside a box, against brute force."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from localpbo_core.optimizers.acquisition import (
    eubo_batch,
    eubo_from_moments,
    maximize_in_box,
    qeubo_from_moments,
    thompson_batch,
    thompson_discrete,
)
from localpbo_core.surrogate import PairwiseGPSurrogate


def _random_moments(k: int, seed: int) -> tuple[torch.Tensor, torch.Tensor]:
    g = torch.Generator().manual_seed(seed)
    mean = torch.randn(k, generator=g, dtype=torch.float64)
    a = torch.randn(k, k, generator=g, dtype=torch.float64)
    return mean, a @ a.T / k + 0.1 * torch.eye(k, dtype=torch.float64)


def _brute_force_max(mean: np.ndarray, cov: np.ndarray, n: int, seed: int) -> float:
    rng = np.random.default_rng(seed)
    return float(rng.multivariate_normal(mean, cov, size=n).max(axis=1).mean())


def test_analytic_eubo_matches_monte_carlo() -> None:
    mean, cov = _random_moments(4, 0)
    vals = eubo_from_moments(mean, cov)
    for i in range(3):
        idx = [0, i + 1]
        ref = _brute_force_max(mean[idx].numpy(), cov[np.ix_(idx, idx)].numpy(), 400_000, i)
        assert float(vals[i]) == pytest.approx(ref, abs=5e-3)


@pytest.mark.parametrize("q", [1, 2, 3])
def test_qeubo_fixed_base_samples_match_brute_force(q: int) -> None:
    mean, cov = _random_moments(1 + q, q)
    z = torch.randn(200_000, 1 + q, generator=torch.Generator().manual_seed(9), dtype=torch.float64)
    est = qeubo_from_moments(mean[None], cov[None], z)
    ref = _brute_force_max(mean.numpy(), cov.numpy(), 400_000, 100 + q)
    assert float(est[0]) == pytest.approx(ref, abs=1e-2)
    if q == 1:
        assert float(est[0]) == pytest.approx(float(eubo_from_moments(mean, cov)[0]), abs=1e-2)


def test_maximize_in_box_reaches_the_box_optimum() -> None:
    target = torch.tensor([0.9, -0.2, 0.45], dtype=torch.float64)

    def obj(x: torch.Tensor) -> torch.Tensor:
        return -((x - target) ** 2).sum(-1)

    lb, ub = np.array([0.1, 0.1, 0.1]), np.array([0.6, 0.6, 0.6])
    starts = np.random.default_rng(0).uniform(lb, ub, size=(4, 3))
    xs, fs = maximize_in_box(obj, starts, lb, ub)
    np.testing.assert_allclose(fs, obj(torch.tensor(xs)).numpy())
    np.testing.assert_allclose(xs, np.tile([0.6, 0.1, 0.45], (4, 1)), atol=1e-6)
    assert np.all(xs >= lb) and np.all(xs <= ub)


def test_thompson_batch_maximises_each_path_over_brute_force_grid() -> None:
    centers = torch.tensor([[0.2, 0.7], [0.55, 0.35]], dtype=torch.float64)

    def path(x: torch.Tensor) -> torch.Tensor:
        r = ((x[:, None, :] - centers[None]) ** 2).sum(-1)
        return torch.sin(6 * x[:, :1]) * 0.1 - r

    lb, ub = np.array([0.1, 0.2]), np.array([0.6, 0.8])
    rng = np.random.default_rng(1)
    raw = rng.uniform(lb, ub, size=(256, 2))
    best = thompson_batch(path, raw, lb, ub, num_restarts=5)
    g = np.stack(np.meshgrid(np.linspace(0.1, 0.6, 401), np.linspace(0.2, 0.8, 401)), -1)
    grid = torch.tensor(g.reshape(-1, 2))
    with torch.no_grad():
        vals = path(grid).numpy()
        got = path(torch.tensor(best)).numpy()
    for j in range(2):
        assert got[j, j] >= vals[:, j].max() - 1e-6


def test_eubo_batch_beats_raw_candidates_and_stays_in_box() -> None:
    def mean_cov(xq: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        m = -((xq - 0.3) ** 2).sum(-1)
        c = torch.exp(-0.5 * torch.cdist(xq, xq) ** 2 / 0.05)
        return m, c + 1e-8 * torch.eye(xq.shape[0], dtype=xq.dtype)

    rng = np.random.default_rng(0)
    inc = np.array([0.5, 0.5])
    lb, ub = np.array([0.2, 0.25]), np.array([0.8, 0.75])
    raw = rng.uniform(lb, ub, size=(128, 2))
    for q in (1, 2):
        base = torch.randn(
            256, q + 1, generator=torch.Generator().manual_seed(0), dtype=torch.float64
        )
        x = eubo_batch(mean_cov, inc, raw, lb, ub, q, base, np.random.default_rng(1))
        assert x.shape == (q, 2) and np.all(x >= lb) and np.all(x <= ub)
        inc_t = torch.tensor(inc)[None]
        with torch.no_grad():
            if q == 1:
                m, c = mean_cov(torch.cat([inc_t, torch.tensor(np.vstack([x, raw]))]))
                v = eubo_from_moments(m, c).numpy()
                assert v[0] >= v[1:].max() - 1e-9
            else:
                m, c = mean_cov(torch.cat([inc_t, torch.tensor(x)]))
                best = qeubo_from_moments(m[None], c[None], base)
                pairs = raw[:64].reshape(32, 2, 2)
                for pair in pairs:
                    m2, c2 = mean_cov(torch.cat([inc_t, torch.tensor(pair)]))
                    assert best >= qeubo_from_moments(m2[None], c2[None], base) - 1e-9


def _fitted_surrogate(d: int, n: int, seed: int) -> PairwiseGPSurrogate:
    """Surrogate fitted to ``n`` duels of consecutive uniform points on a quadratic utility."""
    g = torch.Generator().manual_seed(seed)
    X = torch.rand(n + 1, d, generator=g, dtype=torch.float64)
    y = -((X - 0.4) ** 2).sum(-1) * 5.0 + 0.5 * torch.sin(6.0 * X[:, 0])
    i = torch.arange(n)
    win = y[i] > y[i + 1]
    comp = torch.stack([torch.where(win, i, i + 1), torch.where(win, i + 1, i)], dim=1)
    return PairwiseGPSurrogate.fit(X, comp)


def test_thompson_batch_analytic_route_maximises_real_paths_over_brute_force_grid() -> None:
    s = _fitted_surrogate(2, 25, seed=0)
    paths = s.sample_paths(2, torch.Generator().manual_seed(4), num_features=256)
    lb, ub = np.array([0.15, 0.3]), np.array([0.75, 0.85])
    raw = np.random.default_rng(2).uniform(lb, ub, size=(256, 2))
    best = thompson_batch(paths, raw, lb, ub, num_restarts=5)
    assert best.shape == (2, 2) and np.all(best >= lb) and np.all(best <= ub)
    g = np.stack(np.meshgrid(np.linspace(0.15, 0.75, 301), np.linspace(0.3, 0.85, 301)), -1)
    with torch.no_grad():
        vals = paths(torch.tensor(g.reshape(-1, 2))).numpy()
        got = paths(torch.tensor(best)).numpy()
    for j in range(2):
        assert got[j, j] >= vals[:, j].max() - 1e-6
        assert got[j, j] >= paths.values(raw)[:, j].max()  # never worse than the best start


def test_thompson_batch_analytic_and_autograd_routes_agree_and_are_deterministic() -> None:
    d = 6
    s = _fitted_surrogate(d, 40, seed=1)
    center = s.train_inputs[3].numpy()
    lb, ub = np.clip(center - 0.2, 0, 1), np.clip(center + 0.2, 0, 1)
    raw = np.random.default_rng(3).uniform(lb, ub, size=(512, d))

    def run(analytic: bool) -> np.ndarray:
        paths = s.sample_paths(2, torch.Generator().manual_seed(8), num_features=512)
        if analytic:
            return thompson_batch(paths, raw, lb, ub)
        return thompson_batch(lambda x: paths(x), raw, lb, ub)

    a, b, c = run(True), run(True), run(False)
    np.testing.assert_array_equal(a, b)
    paths = s.sample_paths(2, torch.Generator().manual_seed(8), num_features=512)
    with torch.no_grad():
        va = paths(torch.tensor(a)).numpy().diagonal()
        vc = paths(torch.tensor(c)).numpy().diagonal()
    np.testing.assert_allclose(va, vc, rtol=0, atol=1e-6)


def test_thompson_discrete_takes_each_paths_best_raw_candidate_without_repeats() -> None:
    s = _fitted_surrogate(3, 20, seed=2)
    paths = s.sample_paths(4, torch.Generator().manual_seed(5), num_features=256)
    raw = np.random.default_rng(6).random((64, 3))
    got = thompson_discrete(paths, raw)
    vals = paths.values(raw)
    taken: list[int] = []
    for j in range(4):  # brute force: the best row of path j among the rows not yet taken
        order = [i for i in np.argsort(-vals[:, j], kind="stable") if i not in taken]
        taken.append(int(order[0]))
    np.testing.assert_array_equal(got, raw[taken])
    assert len(set(taken)) == 4
    # the autograd route (any callable) picks the same rows
    np.testing.assert_array_equal(thompson_discrete(lambda x: paths(x), raw), got)
    # two paths that agree everywhere still give two different candidates
    twin = thompson_discrete(lambda x: paths(x)[:, :1].repeat(1, 2), raw)
    assert not np.array_equal(twin[0], twin[1])
    with pytest.raises(ValueError, match="raw candidates"):
        thompson_discrete(paths, raw[:3])
