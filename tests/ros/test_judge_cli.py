"""How ``localpbo run`` sets up a person's run: where it starts (``--warm-start``), what the
run config records (a person judges), how a resume keeps the person, and the goal line a
space file gives the page. No browser (tests/ros/test_judge_browser.py drives the page)."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import pytest
from localpbo_ros.bagtools import load_run
from localpbo_ros.commands import add_subcommands, main, run_settings
from localpbo_ros.driver import judged_by_person, make_run_config
from localpbo_ros.judge import goal_of
from localpbo_ros.params import ParameterError
from localpbo_ros.suite import run_suite

from localpbo_core.settings import RunSettings
from localpbo_core.space import parse_space


def settings_of(*argv: str) -> dict:
    parser = argparse.ArgumentParser()
    add_subcommands(parser.add_subparsers())
    return run_settings(parser.parse_args(["run", *argv]))


def test_a_person_on_hopper_starts_at_the_ars_policy() -> None:
    got = settings_of("--task", "hopper", "--oracle", "human", "--budget", "16")
    task = json.loads(got["task_options"])
    warm = json.loads(got["algorithm_options"])["warm_start"]
    assert task["around_ars"] == 0.1 and task["value_range"] > 0
    assert warm == [0.5] * 33 and got["oracle"] == "human"


@pytest.mark.parametrize(
    "argv",
    [
        ("--task", "hopper", "--budget", "16"),  # the simulated oracle: the paper's box
        ("--task", "hopper", "--oracle", "human", "--warm-start", "none"),  # opted out
        ("--task", "swimmer", "--oracle", "human"),  # no ARS policy: the plain box
    ],
)
def test_the_plain_box_otherwise(argv: tuple[str, ...]) -> None:
    got = settings_of(*argv)
    assert got["task_options"] == "{}" and got["algorithm_options"] == "{}"


def test_own_box_or_warm_start_wins() -> None:
    got = settings_of(
        "--task", "walker2d", "--oracle", "human", "--task-options", '{"weight_low": -2.0}'
    )
    assert json.loads(got["task_options"]) == {"weight_low": -2.0}
    got = settings_of("--task", "walker2d", "--warm-start", "ars")
    assert json.loads(got["task_options"])["around_ars"] == 0.05


def test_warm_start_ars_without_a_policy_refused(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["run", "--task", "swimmer", "--warm-start", "ars", "--no-progress"]) == 2
    assert "--warm-start ars: no ARS policy for 'swimmer'" in capsys.readouterr().err


def test_the_run_config_records_a_person_and_resume_never_simulates(tmp_path: Path) -> None:
    settings = {
        "run_id": "person",
        "algorithm": "sobol",
        "task": "swimmer",
        "budget": 3,
        "task_options": '{"episode_steps": 20, "value_range": 50.0}',
        "oracle": "human",  # recorded as a person's run (the simulated oracle answers here)
    }
    summary = run_suite(settings, tmp_path / "person.mcap", timeout_s=60)
    assert summary.state == "done"
    config = load_run(tmp_path / "person.mcap").config
    assert judged_by_person(config) and config.options["oracle"]["kind"] == "person"
    with pytest.raises(ParameterError, match=r"'oracle'.*judged by a person"):
        run_suite({}, tmp_path / "again.mcap", resume=tmp_path / "person.mcap")
    assert not (tmp_path / "again.mcap").exists()
    plain = make_run_config("plain", RunSettings(algorithm="sobol", problem="hartmann6"))
    assert not judged_by_person(plain) and "kind" not in plain.options["oracle"]


def test_a_space_files_goal_is_the_pages_goal_line() -> None:
    space = parse_space(
        {
            "name": "pid",
            "goal": "settles fast without overshoot",
            "value_range": 5.0,
            "parameters": [{"name": "kp", "lower": 0.1, "upper": 10.0}],
        }
    )
    assert space.to_dict()["goal"] == "settles fast without overshoot"
    assert parse_space(space.to_dict()) == space
    config = make_run_config(
        "pid-run", RunSettings(algorithm="sobol", problem="hartmann6"), space=space
    )
    assert goal_of(config) == "settles fast without overshoot"
    hopper = make_run_config("hop", RunSettings(algorithm="sobol", problem="hopper"))
    assert goal_of(hopper).startswith("Better = hops farther forward")
