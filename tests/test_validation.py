"""The shared setting checks of ``localpbo_core.validation`` and the error they raise."""

from __future__ import annotations

import pickle

import numpy as np
import pytest

from localpbo_core.optimizers import InvalidOutcome, Outcome, make_optimizer
from localpbo_core.problems import make_problem
from localpbo_core.validation import (
    SettingError,
    ValidationError,
    check_choice,
    check_float,
    check_int,
    check_theta,
)


def test_setting_error_carries_field_and_reason_and_pickles() -> None:
    err = SettingError("batch_size", "must be an integer >= 1, got 0")
    assert isinstance(err, ValueError)
    assert (err.field, err.reason) == ("batch_size", "must be an integer >= 1, got 0")
    assert str(err) == "batch_size: must be an integer >= 1, got 0"
    back = pickle.loads(pickle.dumps(err))
    assert type(back) is SettingError
    assert (back.field, back.reason, str(back)) == (err.field, err.reason, str(err))


def test_check_int() -> None:
    assert check_int("n", np.int64(3)) == 3 and type(check_int("n", np.int64(3))) is int
    assert check_int("seed", 0, minimum=0) == 0
    for bad in (0, True, 1.0, "2", None):
        with pytest.raises(SettingError) as info:
            check_int("n", bad)
        assert info.value.field == "n"
        assert info.value.reason == f"must be an integer >= 1, got {bad!r}"


def test_check_float_bounds_and_open_ends() -> None:
    assert check_float("x", 0, minimum=0.0) == 0.0
    assert check_float("x", np.float32(0.25), maximum=0.5, maximum_open=True) == 0.25
    with pytest.raises(SettingError, match=r"^x: must lie in \(0, inf\), got 0.0$"):
        check_float("x", 0.0, minimum=0.0, minimum_open=True)
    with pytest.raises(SettingError, match=r"^x: must lie in \[0, 0.5\), got 0.5$"):
        check_float("x", 0.5, minimum=0.0, maximum=0.5, maximum_open=True)
    for bad in (float("nan"), float("inf"), True, "1"):
        with pytest.raises(SettingError, match="must be a finite number"):
            check_float("x", bad)


def test_check_choice() -> None:
    assert check_choice("mode", "a", ("a", "b")) == "a"
    with pytest.raises(SettingError, match=r"^mode: must be one of \('a', 'b'\), got 'c'$"):
        check_choice("mode", "c", ("a", "b"))


def test_check_theta_copies_read_only_and_names_the_field() -> None:
    source = np.array([0.0, 0.5, 1.0])
    arr = check_theta("warm_start", source, 3)
    assert arr is not source and not arr.flags.writeable and source.flags.writeable
    assert arr.dtype == np.float64 and arr.shape == (3,)
    for bad, reason in [
        ([0.5, 0.5], "expected shape (3,), got (2,)"),
        ([[0.5, 0.5, 0.5]], "expected shape (3,), got (1, 3)"),
        ([0.5, np.nan, 0.5], "contains NaN or inf"),
        ([0.5, 1.5, 0.5], "must lie in [0, 1]^3"),
    ]:
        with pytest.raises(SettingError) as info:
            check_theta("warm_start", bad, 3)
        assert (info.value.field, info.value.reason) == ("warm_start", reason)
    with pytest.raises(SettingError, match=r"^theta: must be a numeric vector"):
        check_theta("theta", ["a", "b", "c"], 3)


def test_optimizers_and_problems_raise_setting_errors() -> None:
    with pytest.raises(SettingError) as info:
        make_optimizer("gipbo", 2, seed=0, budget=10, step_size=0.0)
    assert info.value.field == "step_size"
    with pytest.raises(SettingError) as info:
        make_optimizer("sobol", 2, seed=-1, budget=10)
    assert (info.value.field, info.value.reason) == ("seed", "must be an integer >= 0, got -1")
    with pytest.raises(SettingError) as info:
        make_problem("hartmann6").to_native(np.full(5, 0.5))
    assert info.value.field == "theta"


def test_invalid_outcome_carries_field_and_reason() -> None:
    opt = make_optimizer("sobol", 2, seed=0, budget=6)
    opt.ask()
    assert issubclass(InvalidOutcome, ValidationError)
    with pytest.raises(InvalidOutcome) as info:
        opt.tell([Outcome(7, 0)])
    assert info.value.field == "winner"
    assert info.value.reason == "unknown candidate id 7 (ids are 0..1)"
    assert str(info.value) == "winner: unknown candidate id 7 (ids are 0..1)"
    with pytest.raises(InvalidOutcome) as info:
        opt.tell([Outcome(1, 1)])
    assert (info.value.field, info.value.reason) == ("outcome", "self-duel 1 vs 1")
