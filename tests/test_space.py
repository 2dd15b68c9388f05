"""Parameter spaces: the file format, the θ ↔ user-unit maps and every refusal."""

from __future__ import annotations

import math
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from localpbo_core.benchmarks.hostile_space_files import alias_bomb
from localpbo_core.space import MAX_SPACE_BYTES, ParameterSpace, load_space, parse_space
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


# ----------------------------------------------------------------- hostile files


@pytest.mark.timeout(60)
@pytest.mark.parametrize("field", ["description", "value_range", "name"])
def test_alias_bomb_is_refused_fast_in_bounded_memory(tmp_path: Path, field: str) -> None:
    """In a child process limited to 1 GiB of address space and 30 s: refused, not expanded."""
    path = tmp_path / "bomb.yaml"
    path.write_text(alias_bomb(field))
    script = (
        "import resource, sys\n"
        "resource.setrlimit(resource.RLIMIT_AS, (1 << 30, 1 << 30))\n"
        "from localpbo_core.space import load_space\n"
        "from localpbo_core.validation import SettingError\n"
        "try:\n"
        "    load_space(sys.argv[1])\n"
        "except SettingError as exc:\n"
        "    print(exc.field, '|', exc.reason)\n"
        "    sys.exit(3)\n"
    )
    done = subprocess.run(
        [sys.executable, "-c", script, str(path)], capture_output=True, text=True, timeout=30
    )
    assert done.returncode == 3, done.stderr[-2000:]
    field_name, reason = done.stdout.strip().split(" | ", 1)
    assert field_name == "space"
    assert reason.startswith(f"file {path}: uses a YAML anchor or alias"), reason
    assert len(done.stdout) < 400


def test_the_size_limit_is_checked_before_parsing(tmp_path: Path) -> None:
    big = tmp_path / "big.yaml"
    with big.open("w") as stream:  # 10 MB of one description: never parsed, never echoed
        stream.write("parameters:\n  - {name: kd, lower: 0, upper: 1, description: '")
        stream.write("x" * 10_000_000 + "'}\n")
    with pytest.raises(SettingError) as err:
        load_space(big)
    size = big.stat().st_size
    assert err.value.field == "space"
    assert err.value.reason.startswith(f"file {big}: is {size} bytes, more than the limit")
    assert len(str(err.value)) < 300
    with pytest.raises(SettingError) as err:  # inline text too
        load_space('{"parameters": "' + "x" * MAX_SPACE_BYTES + '"}')
    assert err.value.field == "space" and "more than the limit" in err.value.reason


def test_a_device_that_never_ends_is_cut_at_the_limit() -> None:
    with pytest.raises(SettingError) as err:
        load_space("/dev/zero")
    assert err.value.reason == f"file /dev/zero: is more than the limit of {MAX_SPACE_BYTES} " + (
        "bytes (1 MiB)"
    )


def test_long_values_are_quoted_shortened_naming_file_and_field(tmp_path: Path) -> None:
    text = "y" * (MAX_SPACE_BYTES - 200)  # a file just under the limit
    cases = {
        "space.kd.description": f"parameters:\n  - {{name: kd, lower: 0, upper: 1, "
        f"description: '{text}'}}\n",
        "space.kd.lower": f"parameters:\n  - {{name: kd, lower: '{text}', upper: 1}}\n",
        "space.parameters[0].name": f"parameters:\n  - {{name: '{text}', lower: 0, upper: 1}}\n",
        "space.name": f"name: '{text}'\nparameters:\n  - {{name: kd, lower: 0, upper: 1}}\n",
        "space.value_range": f"value_range: ['{text}']\nparameters: []\n",
    }
    for field, body in cases.items():
        path = tmp_path / "long.yaml"
        path.write_text(body)
        with pytest.raises(SettingError) as err:
            load_space(path)
        assert err.value.field == field, err.value
        assert err.value.reason.startswith(f"file {path}: "), err.value.reason[:200]
        assert len(str(err.value)) < 400, str(err.value)[:400]


@pytest.mark.parametrize(
    ("content", "detail"),
    [
        (bytes(range(256)) * 4, "not UTF-8 text"),
        (b"\x00\x01\x02binary", "binary data"),
        (b"- a list\n- of things\n", "got ['a list', 'of things']"),
        (b"just text", "got 'just text'"),
        (b"", "got None"),
    ],
)
def test_non_mappings_are_reported_as_such(tmp_path: Path, content: bytes, detail: str) -> None:
    path = tmp_path / "odd.yaml"
    path.write_bytes(content)
    with pytest.raises(SettingError) as err:
        load_space(path)
    assert err.value.field == "space"
    assert err.value.reason.startswith(f"file {path}: is not a YAML mapping"), err.value.reason
    assert detail in err.value.reason


def test_deep_nesting_is_refused_before_the_parser_slows_down(tmp_path: Path) -> None:
    path = tmp_path / "deep.yaml"
    path.write_text("parameters: " + "[" * 500_000)  # libyaml takes minutes on this whole
    with pytest.raises(SettingError) as err:
        load_space(path)
    assert err.value.field == "space" and "nested more than" in err.value.reason
