"""``localpbo run --space``: the worked example in one process from the command line."""

from __future__ import annotations

from pathlib import Path

import pytest
from localpbo_ros.commands import main
from localpbo_ros.replay import verify

PID_SPACE = (
    Path(__file__).resolve().parents[2] / "ros_ws/src/localpbo_examples/config/pid_space.yaml"
)


def test_run_with_the_example_controller(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    code = main(
        [
            "run",
            *("--space", str(PID_SPACE), "--example-controller", '{"rate_hz": 200.0}'),
            *("--algorithm", "sobol", "--budget", "4", "--run-id", "cli"),
            *("--out", str(tmp_path), "--no-progress"),
        ]
    )
    out = capsys.readouterr().out
    assert code == 0, out
    assert "recommended candidate" in out
    assert verify(tmp_path / "cli.mcap").ok


def test_space_needs_an_evaluator_and_a_valid_file(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    code = main(["run", "--space", str(PID_SPACE), "--out", str(tmp_path), "--no-progress"])
    assert code == 2 and "--bridge or --example-controller" in capsys.readouterr().err
    bad = tmp_path / "bad.yaml"
    bad.write_text("parameters:\n  - {name: kp, lower: 2, upper: 1}\n")
    code = main(
        [
            *("run", "--space", str(bad), "--example-controller"),
            *("--out", str(tmp_path / "o"), "--no-progress"),
        ]
    )
    err = capsys.readouterr().err
    assert code == 2 and "--space" in err and "space.kp.lower" in err
