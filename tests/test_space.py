"""Parameter spaces: the file format, the θ ↔ user-unit maps and every refusal."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from localpbo_core.space import ParameterSpace, load_space, parse_space
from localpbo_core.validation import SettingError

EXAMPLE = Path(__file__).resolve().parents[1] / "ros_ws/src/localpbo_examples/config/pid_space.yaml"


def spec(*params: dict[str, Any], **top: Any) -> dict[str, Any]:
    return {"parameters": list(params), **top}


KP = {"name": "kp", "lower": 0.1, "upper": 100.0, "log": True, "initial": 1.0, "unit": "N/m"}
KD = {"name": "kd", "lower": -2.0, "upper": 2.0}


def test_example_file_parses() -> None:
    space = load_space(EXAMPLE)
    assert space.name == "space:pid" and space.names == ("kp", "ki", "kd")
    assert space.value_range == 2.0
    assert space.initial_native() == pytest.approx((1.0, 0.1, 0.1), rel=1e-12)


def test_maps_linear_and_log_scales() -> None:
    space = parse_space(spec(KP, KD))
    lo, hi = space.to_native(np.zeros(2)), space.to_native(np.ones(2))
    assert tuple(lo) == (0.1, -2.0) and tuple(hi) == (100.0, 2.0)  # exactly the bounds
    mid = space.to_native(np.array([0.5, 0.5]))
    assert mid[0] == pytest.approx(math.sqrt(0.1 * 100.0))  # geometric centre
    assert mid[1] == 0.0
    theta = np.array([0.3, 0.8])
    expected_kp = math.exp(math.log(0.1) + 0.3 * (math.log(100.0) - math.log(0.1)))
    assert space.to_native(theta)[0] == pytest.approx(expected_kp, rel=1e-15)
    np.testing.assert_allclose(space.from_native(space.to_native(theta)), theta, rtol=1e-12)


def test_warm_start_is_theta_of_initial_values() -> None:
    space = parse_space(spec(KP, {**KD, "initial": 1.0}))
    warm = space.warm_start()
    assert warm is not None
    assert warm[0] == pytest.approx(1 / 3) and warm[1] == pytest.approx(0.75)
    assert parse_space(spec(KD)).warm_start() is None
    # a parameter without initial value starts at its centre
    partial = parse_space(spec(KP, KD)).warm_start()
    assert partial is not None and partial[1] == 0.5


def test_round_trip_through_dict_and_file(tmp_path: Path) -> None:
    space = parse_space(spec(KP, KD, name="arm", value_range=3.0))
    assert parse_space(space.to_dict()) == space
    path = tmp_path / "my gains.yaml"
    path.write_text("parameters:\n  - {name: kp, lower: 1e-3, upper: 2}\n")
    loaded = load_space(path)
    assert loaded.label == "my_gains" and loaded.lower == (0.001,)  # YAML text 1e-3 is a number
    assert math.isnan(loaded.value_range)
    assert load_space('{"parameters": [{"name": "a", "lower": 0, "upper": 1}]}').dim == 1


def test_no_evaluation_of_its_own() -> None:
    space = parse_space(spec(KD))
    with pytest.raises(NotImplementedError):
        space.evaluate(np.array([0.5]), 0)
    with pytest.raises(NotImplementedError):
        space.evaluate_native(np.array([0.0]), 0)


@pytest.mark.parametrize(
    ("obj", "field"),
    [
        ([], "space"),
        ({}, "space.parameters"),
        (spec(), "space.parameters"),
        ({"parameters": [KD], "colour": "red"}, "space.colour"),
        (spec(KD, name="bad name"), "space.name"),
        (spec(KD, value_range=0), "space.value_range"),
        (spec(KD, {"lower": 0, "upper": 1}), "space.parameters[1].name"),
        (spec(KD, {"name": "1x", "lower": 0, "upper": 1}), "space.parameters[1].name"),
        (spec(KD, KD), "space.parameters[1].name"),
        (spec(KD, {"name": "ki", "upper": 1}), "space.ki.lower"),
        (spec({**KD, "lower": 2.0}), "space.kd.lower"),
        (spec({**KD, "lower": 3.0}), "space.kd.lower"),
        (spec({**KD, "upper": float("inf")}), "space.kd.upper"),
        (spec({**KD, "upper": "high"}), "space.kd.upper"),
        (spec({**KP, "lower": 0.0}), "space.kp.lower"),
        (spec({**KP, "lower": -1.0}), "space.kp.lower"),
        (spec({**KP, "log": "yes"}), "space.kp.log"),
        (spec({**KP, "initial": 200.0}), "space.kp.initial"),
        (spec({**KP, "initial": 0.01}), "space.kp.initial"),
        (spec({**KP, "gain": 2}), "space.kp.gain"),
        (spec({**KP, "unit": 3}), "space.kp.unit"),
        (spec(KD, "kp"), "space.parameters[1]"),
    ],
)
def test_bad_spaces_are_refused_naming_the_field(obj: Any, field: str) -> None:
    with pytest.raises(SettingError) as err:
        parse_space(obj)
    assert err.value.field == field, str(err.value)


def test_bad_files_are_refused(tmp_path: Path) -> None:
    with pytest.raises(SettingError) as err:
        load_space(tmp_path / "missing.yaml")
    assert err.value.field == "space" and "cannot read" in err.value.reason
    broken = tmp_path / "broken.yaml"
    broken.write_text("parameters: [unclosed\n")
    with pytest.raises(SettingError) as err:
        load_space(broken)
    assert err.value.field == "space" and "not YAML" in err.value.reason
    with pytest.raises(SettingError) as err:
        load_space("{not json")
    assert err.value.field == "space"


def test_from_native_refuses_values_outside_the_box() -> None:
    space: ParameterSpace = parse_space(spec(KP))
    with pytest.raises(SettingError) as err:
        space.from_native([1000.0])
    assert err.value.field == "kp"
