"""The stored value ranges are reproduced by the documented calibration command."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from localpbo_core.experiments import load_spec
from localpbo_core.problems import make_problem
from localpbo_core.problems.calibrate import main, sobol_points, sobol_values, spread, value_range
from localpbo_core.problems.synthetic import SYNTHETIC_VALUE_RANGES


@pytest.mark.parametrize("name", sorted(SYNTHETIC_VALUE_RANGES))
def test_synthetic_value_range_reproduced(name: str) -> None:
    width, low, high = value_range(name, 10_000)
    assert width == pytest.approx(make_problem(name).value_range, rel=1e-12)
    assert high - low == pytest.approx(width)


SOBOL_VALUES = Path(__file__).with_name("data") / "mujoco_sobol_values.json"
"""``sobol_values(name, 256)`` of each MuJoCo task (made once by that call; an episode of
Swimmer takes about 0.2 s, so the 256 take minutes on a loaded machine)."""

SPOT_CHECKS = 16
"""Points of the 256 evaluated again in each test run, evenly spread."""


@pytest.mark.parametrize("name", ["hopper", "swimmer", "walker2d"])
def test_mujoco_value_range_reproduced(name: str) -> None:
    """The constants follow from the 256 Sobol values, and today's code gives those values
    bit for bit (checked on 16 of them, evenly spread)."""
    from localpbo_sims import MAX_MIN_VALUE_RANGES

    values = np.array(json.loads(SOBOL_VALUES.read_text())[name])
    assert values.shape == (256,)
    problem = make_problem(name)
    points = sobol_points(problem.dim, 256, seed=0)
    for i in np.linspace(0, 255, SPOT_CHECKS).round().astype(int):
        assert problem.true_value(points[i]) == values[i], (name, i)
    width, _, _ = spread(values)
    assert width == pytest.approx(MAX_MIN_VALUE_RANGES[name], rel=1e-12)
    # the default and the policy specs' noise scale: the 1st-99th percentile spread
    robust, low, high = spread(values, (1, 99))
    assert values.min() <= low < high <= values.max() and robust < width
    assert robust == pytest.approx(problem.value_range, rel=1e-12)
    for spec in ("policy_warm_start", "policy_no_warm_start"):
        for run in load_spec(spec).runs():
            if run.problem_label == name:
                assert run.settings.problem_options["value_range"] == pytest.approx(
                    robust, rel=1e-12
                )


def test_sobol_points_are_seeded() -> None:
    a, b, c = sobol_points(6, 8, 0), sobol_points(6, 8, 0), sobol_points(6, 8, 1)
    assert (a == b).all() and not (a == c).all()
    assert a.min() >= 0 and a.max() <= 1


def test_cli_prints_value_range(capsys: pytest.CaptureFixture[str]) -> None:
    main(["--problem", "hartmann6", "--points", "1024"])
    assert "hartmann6: value_range=" in capsys.readouterr().out
    main(["--problem", "hartmann6", "--points", "1024", "--quantiles", "1,99"])
    out = capsys.readouterr().out
    width, low, high = value_range("hartmann6", 1024, (1, 99))
    assert f"value_range={width!r} (percentiles 1, 99: {low:.6g}, {high:.6g};" in out


def test_mujoco_values_do_not_depend_on_the_worker_processes() -> None:
    one = sobol_values("hopper", 6, workers=1)
    two = sobol_values("hopper", 6, workers=2)
    assert one.tobytes() == two.tobytes()
