"""Registry: names, errors, lazy import of the MuJoCo tasks, protocol conformance."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

from localpbo_core.problems import Problem, available_problems, make_problem


def test_available_problems() -> None:
    assert available_problems() == [
        "gp_sample",
        "hartmann6",
        "hopper",
        "levy32",
        "rosenbrock16",
        "styblinskitang32",
        "styblinskitang64",
        "swimmer",
        "walker2d",
    ]


@pytest.mark.parametrize("name", ["hartmann6", "levy32", "hopper", "swimmer", "walker2d"])
def test_problems_satisfy_protocol(name: str) -> None:
    problem = make_problem(name)
    assert isinstance(problem, Problem)
    assert problem.name == name
    theta = np.full(problem.dim, 0.5)
    assert problem.to_native(theta).shape == (problem.dim,)
    assert np.isfinite(problem.value_range) and problem.value_range > 0


def test_mujoco_options_pass_through() -> None:
    task = make_problem("hopper", alive_bonus=True)
    assert task.alive_bonus is True


def test_unknown_problem_lists_valid_names() -> None:
    with pytest.raises(ValueError, match="problem") as info:
        make_problem("ackley")
    for name in available_problems():
        assert name in str(info.value)


def test_unknown_options_raise() -> None:
    with pytest.raises(ValueError, match="noise"):
        make_problem("hartmann6", noise=0.1)
    with pytest.raises(ValueError, match="frame_skip"):
        make_problem("hopper", frame_skip=2)


def test_core_does_not_import_mujoco_until_needed() -> None:
    code = (
        "import sys; import localpbo_core.problems as p; p.make_problem('hartmann6'); "
        "print('mujoco' in sys.modules, 'localpbo_sims' in sys.modules, 'gymnasium' in sys.modules)"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True
    ).stdout.strip()
    assert out == "False False False"
