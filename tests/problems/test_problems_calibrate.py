"""The stored value ranges are reproduced by the documented calibration command."""

from __future__ import annotations

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


@pytest.mark.parametrize(
    "name", ["hopper", "walker2d", pytest.param("swimmer", marks=pytest.mark.slow)]
)
def test_mujoco_value_range_reproduced(name: str) -> None:
    from localpbo_sims import MAX_MIN_VALUE_RANGES

    values = sobol_values(name, 256)
    width, _, _ = spread(values)
    assert width == pytest.approx(MAX_MIN_VALUE_RANGES[name], rel=1e-12)
    # the default and the policy specs' noise scale: the 1st-99th percentile spread
    robust, low, high = spread(values, (1, 99))
    assert values.min() <= low < high <= values.max() and robust < width
    assert robust == pytest.approx(make_problem(name).value_range, rel=1e-12)
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
