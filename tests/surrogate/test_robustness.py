"""Robustness, input validation and warm start of the pairwise GP surrogate."""

from __future__ import annotations

import pytest
import torch

from localpbo_core.surrogate import PairwiseGPSurrogate


def test_duplicates_are_merged_and_self_duels_dropped(duels):
    X, comp = duels(3, 12, seed=1)
    # X[13] is X[2] moved by less than the 1e-4 tolerance; its duel against 2 is a self-duel.
    X2 = torch.cat([X, (X[2] + 5e-5).clamp(0, 1)[None]])
    comp2 = torch.cat([comp, torch.tensor([[13, 2], [13, 5]])])
    merged = PairwiseGPSurrogate.fit(X2, comp2, lengthscale=0.3, outputscale=2.0)
    direct = PairwiseGPSurrogate.fit(
        X, torch.cat([comp, torch.tensor([[2, 5]])]), lengthscale=0.3, outputscale=2.0
    )
    assert merged.train_inputs.shape == X.shape
    assert merged.index_map[13] == 2 and (merged.index_map[:13] == torch.arange(13)).all()
    assert merged.winners.numel() == comp.shape[0] + 1
    torch.testing.assert_close(merged.utility, direct.utility, rtol=1e-12, atol=1e-12)


def test_only_self_duels_is_an_error():
    X = torch.tensor([[0.2, 0.2], [0.2, 0.20001]], dtype=torch.float64)
    with pytest.raises(ValueError, match="self-duels"):
        PairwiseGPSurrogate.fit(X, torch.tensor([[0, 1]]))


def test_single_comparison_and_d1():
    X = torch.tensor([[0.2], [0.7]], dtype=torch.float64)
    s = PairwiseGPSurrogate.fit(X, torch.tensor([[1, 0]]))
    assert s.utility[1] > s.utility[0]
    assert s.mean_gradient(torch.tensor([0.45], dtype=torch.float64)).item() > 0
    assert 0.5 < s.preference_probability(X[1], X[0]).item() < 1.0
    assert torch.isfinite(s.gradient_covariance(X[0])).all()


def test_warm_start_reaches_cold_optimum(duels):
    X, comp = duels(4, 30, seed=6, scale=4.0)
    first = PairwiseGPSurrogate.fit(X[:30], comp[:29])
    warm = PairwiseGPSurrogate.fit(X, comp, warm_start=first)
    cold = PairwiseGPSurrogate.fit(X, comp)
    assert abs(warm.log_marginal_likelihood - cold.log_marginal_likelihood) < 1e-5
    torch.testing.assert_close(warm.lengthscale, cold.lengthscale, rtol=0, atol=2e-3)
    torch.testing.assert_close(warm.utility, cold.utility, rtol=0, atol=1e-3)
    # fixed hyperparameters: warm and cold MAPs agree to Newton precision
    w = PairwiseGPSurrogate.fit(X, comp, 0.3, 2.0, warm_start=first)
    c = PairwiseGPSurrogate.fit(X, comp, 0.3, 2.0)
    torch.testing.assert_close(w.utility, c.utility, rtol=1e-10, atol=1e-10)


@pytest.mark.slow
def test_d102_with_1530_comparisons(duels):
    X, comp = duels(102, 1530, seed=8)
    s = PairwiseGPSurrogate.fit(X, comp)
    x = X[-1]
    assert s.utility.shape == (1531,)
    assert torch.isfinite(s.mean_hessian(x)).all()
    assert (torch.linalg.eigvalsh(s.gradient_covariance(x)) > -1e-8).all()


def test_d102_fixed_hyperparameters(duels):
    X, comp = duels(102, 300, seed=9)
    s = PairwiseGPSurrogate.fit(X, comp, lengthscale=0.5, outputscale=3.0)
    g = s.mean_gradient(X[0])
    torch.testing.assert_close(g, torch.func.grad(s.mean)(X[0]), rtol=1e-9, atol=1e-12)
    assert s.gradient_covariance(X[0]).shape == (102, 102)


GOOD_X = torch.tensor([[0.1, 0.2], [0.3, 0.4]], dtype=torch.float64)
GOOD_C = torch.tensor([[0, 1]])


@pytest.mark.parametrize(
    ("X", "comp", "kwargs", "match"),
    [
        (GOOD_X.clone().fill_(float("nan")), GOOD_C, {}, "NaN or inf"),
        (
            torch.tensor([[0.1, float("inf")], [0.3, 0.4]], dtype=torch.float64),
            GOOD_C,
            {},
            "NaN or inf",
        ),
        (GOOD_X + 1.0, GOOD_C, {}, r"\[0, 1\]"),
        (GOOD_X - 0.5, GOOD_C, {}, r"\[0, 1\]"),
        (GOOD_X, torch.tensor([[0, 2]]), {}, "out of range"),
        (GOOD_X, torch.tensor([[-1, 0]]), {}, "out of range"),
        (GOOD_X, torch.tensor([0, 1]), {}, "shape"),
        (GOOD_X, torch.tensor([[0.0, 1.0]]), {}, "dtype"),
        (GOOD_X.float(), GOOD_C, {}, "dtype"),
        (GOOD_X[0], GOOD_C, {}, "shape"),
        (GOOD_X.numpy(), GOOD_C, {}, "torch.Tensor"),
        (GOOD_X, GOOD_C, {"lengthscale": torch.ones(3)}, "lengthscale"),
        (GOOD_X, GOOD_C, {"lengthscale": -1.0}, "lengthscale"),
        (GOOD_X, GOOD_C, {"outputscale": float("nan")}, "outputscale"),
        (GOOD_X, GOOD_C, {"eps_reg": -1.0}, "eps_reg"),
    ],
)
def test_bad_input_raises_value_error(X, comp, kwargs, match):
    with pytest.raises(ValueError, match=match):
        PairwiseGPSurrogate.fit(X, comp, **kwargs)


def test_bad_query_raises_value_error():
    s = PairwiseGPSurrogate.fit(GOOD_X, GOOD_C, lengthscale=0.3, outputscale=1.0)
    with pytest.raises(ValueError, match="shape"):
        s.mean(torch.zeros(3, dtype=torch.float64))
    with pytest.raises(ValueError, match="dtype"):
        s.mean_gradient(torch.zeros(2, dtype=torch.float32))
    with pytest.raises(ValueError, match="orders"):
        s.covariance_blocks(torch.zeros(2, dtype=torch.float64), orders=(3,))
    with pytest.raises(ValueError, match="generator"):
        s.sample_paths(2, None)  # type: ignore[arg-type]
