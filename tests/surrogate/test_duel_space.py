"""The duel-space Laplace approximation (duel_space.py) against the whitened form (laplace.py):
same MAP, evidence and hyperparameter gradient, also when the duel covariance is singular."""

from __future__ import annotations

import pytest
import torch
from surrogate_helpers import learn_kwargs

from localpbo_core.surrogate import PairwiseGPSurrogate
from localpbo_core.surrogate.data import consolidate
from localpbo_core.surrogate.duel_space import (
    dual_from_utilities,
    duel_covariance,
    find_mode,
)
from localpbo_core.surrogate.hyperparameters import evaluate_with_gradient, learn_hyperparameters
from localpbo_core.surrogate.kernel import se_kernel
from localpbo_core.surrogate.laplace import find_map


def _duel_matrix(winners: torch.Tensor, losers: torch.Tensor, p: int) -> torch.Tensor:
    H = torch.zeros(winners.shape[0], p, dtype=torch.float64)
    H[torch.arange(winners.shape[0]), winners] = 1.0
    H[torch.arange(winners.shape[0]), losers] = -1.0
    return H


def _dense_graph(d: int, p: int, m: int, seed: int):
    """``m > p`` duels with cycles and repeated pairs (``H K H^T`` is singular)."""
    g = torch.Generator().manual_seed(seed)
    X = torch.rand(p, d, generator=g, dtype=torch.float64)
    y = 4.0 * torch.sin(3.0 * X.sum(-1))
    a = torch.randint(0, p, (m,), generator=g)
    b = (a + 1 + torch.randint(0, p - 1, (m,), generator=g)) % p
    noisy = y[a] - y[b] + 0.7 * torch.randn(m, generator=g, dtype=torch.float64)
    comp = torch.stack([torch.where(noisy > 0, a, b), torch.where(noisy > 0, b, a)], 1)
    comp = torch.cat([comp, comp[:5]])  # exact repeats
    return consolidate(X, comp)


def test_duel_covariance_is_h_k_h_transpose(duels) -> None:
    X, comp = duels(3, 20, 1)
    data = consolidate(X, comp)
    K = se_kernel(data.X, data.X, torch.full((3,), 0.3, dtype=torch.float64), 2.0)
    H = _duel_matrix(data.winners, data.losers, data.X.shape[0])
    torch.testing.assert_close(
        duel_covariance(K, data.winners, data.losers), H @ K @ H.T, rtol=0, atol=1e-13
    )


@pytest.mark.parametrize("graph", ["tree", "dense"])
def test_duel_and_whitened_forms_agree(duels, graph: str) -> None:
    if graph == "tree":
        X, comp = duels(5, 40, 3, scale=6.0)
        data = consolidate(X, comp)
    else:
        data = _dense_graph(4, 25, 70, seed=2)
        assert data.winners.shape[0] > data.X.shape[0]
    ls = torch.linspace(0.15, 0.45, data.X.shape[1], dtype=torch.float64)
    f0 = torch.zeros(data.X.shape[0], dtype=torch.float64)
    for os_ in (0.5, 7.0, 95.0):
        args = (data.X, data.winners, data.losers, ls, os_, f0, 1e-8, None)
        v_d, gl_d, go_d, f_d = evaluate_with_gradient(*args, form="duels")
        v_w, gl_w, go_w, f_w = evaluate_with_gradient(*args, form="whitened")
        assert abs(v_d - v_w) <= 1e-9 * (1.0 + abs(v_w))
        scale = float(torch.cat([gl_w, go_w.reshape(1)]).abs().max())
        torch.testing.assert_close(gl_d, gl_w, rtol=0, atol=1e-8 * scale)
        torch.testing.assert_close(go_d, go_w, rtol=0, atol=1e-8 * scale)
        torch.testing.assert_close(f_d, f_w, rtol=0, atol=1e-7 * (1.0 + float(f_w.abs().max())))


def test_mode_matches_the_whitened_map_from_any_start(duels) -> None:
    X, comp = duels(4, 30, 7, scale=5.0)
    data = consolidate(X, comp)
    ls = torch.full((4,), 0.25, dtype=torch.float64)
    K = se_kernel(data.X, data.X, ls, 3.0) + 3e-8 * torch.eye(data.X.shape[0], dtype=torch.float64)
    L = torch.linalg.cholesky(K)
    v_hat, _ = find_map(L, data.winners, data.losers, torch.zeros(data.X.shape[0]).double())
    f_ref = L @ v_hat
    M = duel_covariance(K, data.winners, data.losers)
    gen = torch.Generator().manual_seed(0)
    for start in (torch.zeros(data.X.shape[0]), 5.0 * torch.randn(data.X.shape[0], generator=gen)):
        a0 = dual_from_utilities(start.double(), data.winners, data.losers)
        a, _, _ = find_mode(M, a0)
        f = a @ (K[data.winners] - K[data.losers])
        torch.testing.assert_close(f, f_ref, rtol=0, atol=1e-8)


def test_fits_with_either_form_reach_the_same_optimum(duels) -> None:
    X, comp = duels(4, 45, 11, scale=5.0)
    data = consolidate(X, comp)
    kw = learn_kwargs(data, z_limit=None)
    a = learn_hyperparameters(data.X, data.winners, data.losers, form="duels", **kw)
    b = learn_hyperparameters(data.X, data.winners, data.losers, form="whitened", **kw)
    assert abs(a.log_marginal_likelihood - b.log_marginal_likelihood) < 1e-7
    torch.testing.assert_close(a.lengthscale, b.lengthscale, rtol=0, atol=1e-4)
    torch.testing.assert_close(a.v_hat, b.v_hat, rtol=0, atol=1e-6)


@pytest.mark.parametrize(("z_limit", "form"), [(3.0, "duels"), (None, "dual")])
def test_bad_form_is_refused(duels, z_limit, form) -> None:
    """The duel form needs the exact probit; unknown forms are refused."""
    X, comp = duels(2, 10, 0)
    data = consolidate(X, comp)
    with pytest.raises(ValueError, match="form"):
        evaluate_with_gradient(
            data.X,
            data.winners,
            data.losers,
            torch.full((2,), 0.3, dtype=torch.float64),
            1.0,
            torch.zeros(data.X.shape[0], dtype=torch.float64),
            1e-8,
            z_limit,
            form=form,
        )


def test_unknown_form_is_refused_at_fit_time(duels) -> None:
    X, comp = duels(2, 10, 0)
    with pytest.raises(ValueError, match="form"):
        PairwiseGPSurrogate.fit(X, comp, lengthscale=0.3, outputscale=1.0, form="dual")
