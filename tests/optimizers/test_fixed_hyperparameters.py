"""The shared ``hyperparameters`` option (within-model runs, paper App. D.4): every
model-based algorithm accepts it, and the surrogate's hyperparameters equal it after every fit."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from localpbo_core.loop import run_session
from localpbo_core.optimizers.registry import optimizer_options
from localpbo_core.optimizers.surrogate_refit import SurrogateRefitter
from localpbo_core.session import Session
from localpbo_core.settings import RunSettings
from localpbo_core.validation import SettingError

MODEL_BASED = ("gipbo", "gipbor", "prefsqp", "qeubo", "turpbo")
BUDGETS = {"gipbo": 9, "gipbor": 9, "prefsqp": 12, "qeubo": 6, "turpbo": 8}
FAST = {"qeubo": {"num_raw_samples": 64, "num_restarts": 2}, "turpbo": {"num_raw_samples": 64}}


@pytest.fixture
def fits(monkeypatch: pytest.MonkeyPatch) -> list:
    """Every surrogate a :class:`SurrogateRefitter` returns, in order."""
    seen: list = []
    original = SurrogateRefitter.refit

    def spy(self: SurrogateRefitter, X: np.ndarray, comps: np.ndarray, ties=None):
        fitted = original(self, X, comps, ties)
        seen.append(fitted)
        return fitted

    monkeypatch.setattr(SurrogateRefitter, "refit", spy)
    return seen


@pytest.mark.parametrize("algorithm", MODEL_BASED)
def test_fixed_hyperparameters_hold_after_every_fit(algorithm: str, fits: list) -> None:
    fixed = {"lengthscale": 0.1, "outputscale": 1.0}
    options = {"hyperparameters": fixed, **FAST.get(algorithm, {})}
    settings = RunSettings(
        algorithm,
        "gp_sample",
        seed=1,
        budget=BUDGETS[algorithm],
        optimizer_options=options,
        problem_options={"dim": 3, "lengthscale": 0.1},
    )
    run_session(Session(settings))
    assert len(fits) >= 1
    for s in fits:
        torch.testing.assert_close(s.lengthscale, torch.full((3,), 0.1, dtype=torch.float64))
        assert float(s.outputscale) == 1.0


def test_without_the_option_hyperparameters_are_learned(fits: list) -> None:
    settings = RunSettings("prefsqp", "hartmann6", seed=1, budget=14)
    run_session(Session(settings))
    assert fits and any(float(s.outputscale) != 1.0 for s in fits)


def test_ard_lengthscale_and_outputscale_only(fits: list) -> None:
    ls = [0.2, 0.3, 0.4]
    settings = RunSettings(
        "turpbo",
        "gp_sample",
        seed=0,
        budget=5,
        optimizer_options={"hyperparameters": {"lengthscale": ls}, "num_raw_samples": 64},
        problem_options={"dim": 3, "lengthscale": 0.5},
    )
    run_session(Session(settings))
    for s in fits:
        np.testing.assert_array_equal(s.lengthscale.numpy(), ls)
    fits.clear()
    settings = settings.replace(optimizer_options={"hyperparameters": {"outputscale": 2.5}})
    run_session(Session(settings))
    assert fits and all(float(s.outputscale) == 2.5 for s in fits)


@pytest.mark.parametrize(
    ("value", "field"),
    [
        ({"lengthscale": -1.0}, "optimizer_options.hyperparameters.lengthscale"),
        ({"lengthscale": [0.1, 0.2]}, "optimizer_options.hyperparameters.lengthscale"),
        ({"lengthscale": "short"}, "optimizer_options.hyperparameters.lengthscale"),
        ({"outputscale": 0.0}, "optimizer_options.hyperparameters.outputscale"),
        ({"noise": 0.1}, "optimizer_options.hyperparameters.noise"),
        ({}, "optimizer_options.hyperparameters"),
        (0.1, "optimizer_options.hyperparameters"),
    ],
)
@pytest.mark.parametrize("algorithm", MODEL_BASED)
def test_bad_values_raise_setting_error(algorithm: str, value: object, field: str) -> None:
    settings = RunSettings(algorithm, "hartmann6", optimizer_options={"hyperparameters": value})
    with pytest.raises(SettingError) as info:
        Session(settings)
    assert info.value.field == field


@pytest.mark.parametrize("algorithm", ["sobol", "glisp"])
def test_model_free_algorithms_do_not_take_it(algorithm: str) -> None:
    assert "hyperparameters" not in optimizer_options(algorithm)
    settings = RunSettings(
        algorithm, "hartmann6", optimizer_options={"hyperparameters": {"lengthscale": 0.1}}
    )
    with pytest.raises(SettingError) as info:
        Session(settings)
    assert info.value.field == "optimizer_options.hyperparameters"
