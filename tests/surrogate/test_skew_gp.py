"""The skew-GP preference posterior (exact probit posterior sampled by LinESS) against
independent references: rejection sampling from the prior plus noise, closed-form truncated
normal moments, dense linear algebra and finite differences."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.special import ndtr

from localpbo_core.surrogate.skew_gp import (
    DuelPosteriorChain,
    duel_matrix,
    lin_ess_step,
    se_kernel_np,
    truncated_standard_normal_above,
)

# A tiny problem: 4 points, 5 duels, including a cycle-breaking "surprise" (3 beats 1 after
# 1 beat 2 and 2 beat 3) so the posterior is clearly skewed, not Gaussian.
X4 = np.array([[0.1, 0.2], [0.4, 0.3], [0.5, 0.8], [0.9, 0.6]])
WIN = np.array([0, 0, 1, 2, 3])
LOSE = np.array([1, 2, 2, 3, 1])
LS = np.array([0.3, 0.4])
OS = 2.0


def _rejection(K: np.ndarray, noise_var: float, n: int, seed: int) -> np.ndarray:
    """Independent reference: ``f ~ N(0, K)``, ``eps ~ N(0, noise_var)`` per duel, keep the
    draws under which every duel of (WIN, LOSE) is observed (``f_w - f_l + eps > 0``)."""
    rng = np.random.default_rng(seed)
    w, v = np.linalg.eigh(K)
    root = v * np.sqrt(np.clip(w, 0.0, None))
    f = rng.standard_normal((n, K.shape[0])) @ root.T
    eps = math.sqrt(noise_var) * rng.standard_normal((n, WIN.size))
    keep = ((f[:, WIN] - f[:, LOSE] + eps) > 0).all(axis=1)
    return f[keep]


def _moments_agree(a: np.ndarray, b: np.ndarray, sigmas: float = 4.0) -> bool:
    """Means and variances of the columns of two independent samples agree within
    ``sigmas`` Monte Carlo standard errors (SE of a variance: sqrt((m4 - v^2) / n))."""

    def stats(s: np.ndarray) -> tuple[np.ndarray, ...]:
        n = s.shape[0]
        mean = s.mean(0)
        c = s - mean
        var = (c**2).mean(0)
        m4 = (c**4).mean(0)
        return mean, var, var / n, (m4 - var**2) / n

    ma, va, sa_m, sa_v = stats(a)
    mb, vb, sb_m, sb_v = stats(b)
    ok_mean = np.abs(ma - mb) <= sigmas * np.sqrt(sa_m + sb_m)
    ok_var = np.abs(va - vb) <= sigmas * np.sqrt(sa_v + sb_v)
    return bool(ok_mean.all() and ok_var.all())


@pytest.fixture(scope="module")
def reference() -> np.ndarray:
    K = se_kernel_np(X4, X4, LS, OS)
    return _rejection(K, 2.0, 1_500_000, seed=11)


def _chain_samples(num_chains: int, steps: int, seed: int, noise_std: float = 1.0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    chain = DuelPosteriorChain(noise_std=noise_std, num_chains=num_chains)
    chain.update(X4, WIN, LOSE, LS, OS, rng)
    chain.run(steps, rng)
    assert (chain.g > 0).all()
    return chain.sample_latent(rng)


def test_posterior_moments_match_rejection_sampling(reference: np.ndarray) -> None:
    assert reference.shape[0] > 20_000  # enough accepted draws for a sharp reference
    samples = _chain_samples(num_chains=6000, steps=60, seed=1)
    assert _moments_agree(samples, reference)
    # and the posterior is far from the prior: the check has something to detect
    assert np.abs(reference.mean(0)).max() > 0.5


def test_the_moment_check_detects_a_wrong_posterior(reference: np.ndarray) -> None:
    """Power of the check above: the sampler of a different model (preference noise
    sigma = 0.5 instead of 1) and the chain's cold-start proposal without any LinESS step
    (the sequential draw, not the posterior) must both be rejected."""
    assert not _moments_agree(_chain_samples(6000, 60, seed=1, noise_std=0.5), reference)
    assert not _moments_agree(_chain_samples(6000, 0, seed=1), reference)


def test_warm_started_chains_give_the_same_distribution(reference: np.ndarray) -> None:
    """Duels appended one at a time (state extended, few steps each), with other
    hyperparameters in between, end at the posterior of all duels."""
    rng = np.random.default_rng(3)
    chain = DuelPosteriorChain(num_chains=6000)
    assert not chain.update(X4[:2], WIN[:1], LOSE[:1], LS * 2.0, 0.5, rng)
    chain.run(5, rng)
    for m in range(2, WIN.size + 1):
        n = int(max(WIN[:m].max(), LOSE[:m].max())) + 1
        assert chain.update(X4[:n], WIN[:m], LOSE[:m], LS, OS, rng)
        assert (chain.g > 0).all()  # the extension satisfies the new constraint
        chain.run(5, rng)
    chain.run(10, rng)
    assert chain.extended_rows > 0  # the last duels reused the factorisation
    assert _moments_agree(chain.sample_latent(rng), reference)


def test_every_state_satisfies_every_duel_exactly() -> None:
    rng = np.random.default_rng(0)
    n, d = 40, 3
    X = rng.random((n, d))
    y = -((X - 0.5) ** 2).sum(1)
    new = np.arange(1, n)
    old = (rng.random(n - 1) * new).astype(np.int64)
    w = np.where(y[new] > y[old], new, old)
    l_ = np.where(y[new] > y[old], old, new)
    chain = DuelPosteriorChain(num_chains=8)
    # outputscale 50 against noise variance 2: tight, strongly correlated constraints
    for m in (5, 6, 20, n - 1):
        chain.update(X[: m + 1], w[:m], l_[:m], np.full(d, 0.2), 50.0, rng)
        assert (chain.g > 0).all()
        for _ in range(50):
            g = chain.run(1, rng)
            assert g.shape == (8, m)
            assert (g > 0).all()  # exact: every hallucinated difference has the duel's sign


def test_lin_ess_step_keeps_states_in_the_orthant_and_moves() -> None:
    rng = np.random.default_rng(5)
    A = rng.standard_normal((6, 6))
    L = np.linalg.cholesky(A @ A.T + 0.1 * np.eye(6))
    g = np.full((100, 6), 1e-3)
    out = lin_ess_step(g, L, rng)
    assert (out > 0).all()
    assert not np.array_equal(out, g)


def test_cholesky_extension_equals_a_fresh_factorisation() -> None:
    rng = np.random.default_rng(2)
    X = rng.random((12, 4))
    w = np.arange(1, 12)
    l_ = np.zeros(11, dtype=np.int64)
    ls = np.full(4, 0.3)
    chain = DuelPosteriorChain()
    for m in range(1, 12):
        chain.update(X[: m + 1], w[:m], l_[:m], ls, 3.0, rng)
    assert chain.full_factorizations == 1 and chain.extended_rows == 10
    K = se_kernel_np(X, X, ls, 3.0)
    assert np.array_equal(chain.K, K)  # the grown kernel matrix is bit-identical
    H = duel_matrix(w, l_, 12)
    M = H @ K @ H.T + 2.0 * np.eye(11)
    np.testing.assert_allclose(chain.chol_M, np.linalg.cholesky(M), rtol=0, atol=1e-11)


def test_truncated_standard_normal_moments() -> None:
    rng = np.random.default_rng(4)
    n = 200_000
    for a in (-3.0, 0.0, 1.5, 8.0, 40.0):
        u = truncated_standard_normal_above(np.full(n, a), rng)
        assert (u > a).all()
        if a < 30:  # mean of N(0,1) given u > a (inverse Mills ratio)
            mean = math.exp(-0.5 * a * a) / math.sqrt(2 * math.pi) / float(ndtr(-a))
            var = 1.0 + a * mean - mean**2
            assert abs(u.mean() - mean) <= 4.0 * math.sqrt(var / n)
        else:  # far tail: u - a is close to Exp(a)
            assert abs((u - a).mean() - 1.0 / a) <= 4.0 * (1.0 / a) / math.sqrt(n)


def test_conditioned_gp_matches_dense_regression_and_finite_differences() -> None:
    rng = np.random.default_rng(6)
    chain = DuelPosteriorChain()
    chain.update(X4, WIN, LOSE, LS, OS, rng)
    chain.run(20, rng)
    gp = chain.conditioned_gp()
    xq = rng.random((5, 2))
    # dense reference: joint Gaussian of (f(xq), g), conditioned on g
    H = duel_matrix(WIN, LOSE, 4)
    M = H @ se_kernel_np(X4, X4, LS, OS) @ H.T + 2.0 * np.eye(5)
    C = se_kernel_np(xq, X4, LS, OS) @ H.T
    mean_ref = C @ np.linalg.solve(M, chain.g[0])
    var_ref = OS - np.einsum("ij,ij->i", C @ np.linalg.inv(M), C)
    mu, var = gp.mean_var(xq)
    np.testing.assert_allclose(mu, mean_ref, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(var, var_ref, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(chain.latent_mean()[0], gp.mean_var(X4)[0], atol=1e-12)
    _, _, dmu, dvar = gp.mean_var_grad(xq)
    h = 1e-6
    for k in range(2):
        e = np.zeros(2)
        e[k] = h
        mp, vp = gp.mean_var(xq + e)
        mm, vm = gp.mean_var(xq - e)
        np.testing.assert_allclose(dmu[:, k], (mp - mm) / (2 * h), rtol=1e-6, atol=1e-8)
        np.testing.assert_allclose(dvar[:, k], (vp - vm) / (2 * h), rtol=1e-6, atol=1e-8)


def test_same_generator_same_chain() -> None:
    def run(seed: int) -> np.ndarray:
        rng = np.random.default_rng(seed)
        chain = DuelPosteriorChain(num_chains=3)
        chain.update(X4, WIN, LOSE, LS, OS, rng)
        chain.run(7, rng)
        return chain.sample_latent(rng)

    assert np.array_equal(run(8), run(8))
    assert not np.array_equal(run(8), run(9))


def test_duplicate_points_are_fine() -> None:
    """A point proposed twice makes ``K`` singular; ``M = H K H^T + 2 I`` stays positive
    definite and the latent draw still works (jitter on the prior draw only)."""
    rng = np.random.default_rng(7)
    X = np.vstack([X4, X4[1:2]])  # point 4 duplicates point 1
    w = np.array([0, 4, 1, 2])
    l_ = np.array([1, 0, 4, 4])
    chain = DuelPosteriorChain(num_chains=4)
    chain.update(X, w, l_, LS, 1.0e4, rng)
    g = chain.run(50, rng)
    assert (g > 0).all()
    f = chain.sample_latent(rng)
    assert np.isfinite(f).all() and f.shape == (4, 5)
