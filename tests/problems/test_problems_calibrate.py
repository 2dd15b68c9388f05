"""The stored value ranges are reproduced by the documented calibration command."""

from __future__ import annotations

import pytest

from localpbo_core.problems import make_problem
from localpbo_core.problems.calibrate import main, sobol_points, value_range
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
    width, _, _ = value_range(name, 256)
    assert width == pytest.approx(make_problem(name).value_range, rel=1e-12)


def test_sobol_points_are_seeded() -> None:
    a, b, c = sobol_points(6, 8, 0), sobol_points(6, 8, 0), sobol_points(6, 8, 1)
    assert (a == b).all() and not (a == c).all()
    assert a.min() >= 0 and a.max() <= 1


def test_cli_prints_value_range(capsys: pytest.CaptureFixture[str]) -> None:
    main(["--problem", "hartmann6", "--points", "1024"])
    assert "hartmann6: value_range=" in capsys.readouterr().out
