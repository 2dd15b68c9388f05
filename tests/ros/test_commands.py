"""CLI wiring: defaults form a valid run; refused settings exit 2 naming the parameter."""

from __future__ import annotations

import argparse

from localpbo_ros.commands import add_subcommands, main, run_settings
from localpbo_ros.optimizer_node import PARAMS, config_from_settings


def parse(argv):
    parser = argparse.ArgumentParser()
    add_subcommands(parser.add_subparsers(dest="command", required=True))
    return parser.parse_args(argv)


def test_default_run_is_turpbo_on_swimmer() -> None:
    args = parse(["run"])
    settings = {p.name: p.default for p in PARAMS}
    settings.update(run_settings(args))
    settings["algorithm_options"] = {}
    settings["task_options"] = {}
    config = config_from_settings(settings)
    assert (config.algorithm, config.task, config.budget, config.dim) == (
        "turpbo",
        "swimmer",
        162,
        16,
    )
    assert args.func.__name__ == "cmd_run"
    assert parse(["replay", "x.mcap", "--verify"]).func.__name__ == "cmd_replay"
    assert parse(["bag-info", "x.mcap"]).func.__name__ == "cmd_bag_info"


def test_refused_setting_exits_2(tmp_path, capsys) -> None:
    code = main(["run", "--algorithm", "simplex", "--out", str(tmp_path), "--no-progress"])
    assert code == 2
    assert "invalid parameter 'algorithm'" in capsys.readouterr().err
    code = main(["run", "--budget", "-1", "--out", str(tmp_path), "--no-progress"])
    assert code == 2 and "'budget'" in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []  # no empty bag left behind


def test_a_person_judging_gets_ties_unless_told_otherwise() -> None:
    from localpbo_core.settings import DEFAULT_TIE_THRESHOLD

    assert run_settings(parse(["run"]))["tie_threshold"] == 0.0
    assert run_settings(parse(["run", "--oracle", "human"]))["tie_threshold"] == (
        DEFAULT_TIE_THRESHOLD
    )
    human_without = parse(["run", "--oracle", "human", "--tie-threshold", "0"])
    assert run_settings(human_without)["tie_threshold"] == 0.0
    assert run_settings(parse(["run", "--tie-threshold"]))["tie_threshold"] == (
        DEFAULT_TIE_THRESHOLD
    )
    assert run_settings(parse(["run", "--tie-threshold", "0.4"]))["tie_threshold"] == 0.4


def test_a_person_judging_gets_speculation_unless_told_otherwise() -> None:
    assert run_settings(parse(["run"]))["speculate"] is False
    assert run_settings(parse(["run", "--speculate"]))["speculate"] is True
    assert run_settings(parse(["run", "--oracle", "human"]))["speculate"] is True
    no = parse(["run", "--oracle", "human", "--no-speculate"])
    assert run_settings(no)["speculate"] is False
