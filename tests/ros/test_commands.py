"""CLI wiring: defaults form a valid run; refused settings exit 2 naming the parameter."""

from __future__ import annotations

import argparse
import json

from localpbo_ros.commands import add_subcommands, main, run_settings
from localpbo_ros.optimizer_node import PARAMS, config_from_settings

from localpbo_core.presets import expand
from localpbo_core.settings import DEFAULT_ALGORITHM


def parse(argv):
    parser = argparse.ArgumentParser()
    add_subcommands(parser.add_subparsers(dest="command", required=True))
    return parser.parse_args(argv)


def test_default_run_is_the_default_algorithm_on_swimmer() -> None:
    """``localpbo run`` without flags: the default algorithm (a preset: its algorithm and its
    options, as ``--algorithm`` names it) on Swimmer, 162 evaluations."""
    args = parse(["run"])
    settings = {p.name: p.default for p in PARAMS}
    settings.update(run_settings(args))
    settings["algorithm_options"] = {}
    settings["task_options"] = {}
    config = config_from_settings(settings)
    algorithm, options = expand(DEFAULT_ALGORITHM, {})
    assert (config.algorithm, config.task, config.budget, config.dim) == (
        algorithm,
        "swimmer",
        162,
        16,
    )
    assert {k: config.options["optimizer"][k] for k in options} == options
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


def test_a_refused_space_file_exits_2_naming_file_and_field(tmp_path, capsys) -> None:
    """Before anything starts: no node, no bag; the message names the file and the field."""
    bomb = tmp_path / "bomb.yaml"
    levels = ['&a0 "lol"'] + [f"&a{k} [{', '.join([f'*a{k - 1}'] * 9)}]" for k in range(1, 10)]
    bomb.write_text(
        f"name: [{', '.join(levels)}]\nparameters: [{{name: kd, lower: 0, upper: 1}}]\n"
    )
    binary = tmp_path / "gains.bin"
    binary.write_bytes(bytes(range(256)))
    low = tmp_path / "low.yaml"
    low.write_text("parameters:\n  - {name: kd, lower: 2, upper: 1}\n")
    out = tmp_path / "out"
    cases = {
        bomb: "space: file {}: uses a YAML anchor or alias",
        binary: "space: file {}: is not a YAML mapping (not UTF-8 text",
        low: "space.kd.lower: file {}: must be below upper",
    }
    for path, says in cases.items():
        argv = ["run", "--space", str(path), "--example-controller", "--out", str(out)]
        assert main([*argv, "--no-progress"]) == 2
        err = capsys.readouterr().err
        assert err.startswith("localpbo run: --space: " + says.format(path)), err
        assert len(err) < 400
    assert not out.exists()


def test_an_unknown_bridge_parameter_exits_2_with_the_near_name(tmp_path, capsys) -> None:
    from pathlib import Path

    space = Path(__file__).resolve().parents[2] / "ros_ws/src/localpbo_examples/config"
    out = tmp_path / "out"
    argv = ["run", "--space", str(space / "pid_space.yaml"), "--example-controller"]
    argv += ["--bridge", '{"trial_duraton_s": 2}', "--out", str(out), "--no-progress"]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "unknown parameter 'trial_duraton_s' (did you mean 'trial_duration_s'?)" in err
    assert not out.exists() or list(out.iterdir()) == []  # no empty bag left behind


def test_a_preset_is_recorded_as_its_algorithm_with_its_options() -> None:
    """``localpbo run --algorithm prefsqp_all`` (the optimizer node's ``algorithm`` parameter)
    makes the run config of PrefSQP with the preset's options given explicitly."""
    from localpbo_core.presets import PRESETS

    options = json.dumps(dict(PRESETS["prefsqp_all"].options))

    def config(argv):
        settings = {p.name: p.default for p in PARAMS}
        settings.update(run_settings(parse(["run", "--task", "hartmann6", "--run-id", "r", *argv])))
        checked = {p.name: p.check(settings[p.name]) for p in PARAMS}
        return config_from_settings(checked)

    preset = config(["--algorithm", "prefsqp_all"])
    explicit = config(["--algorithm", "prefsqp", "--algorithm-options", options])
    assert preset.algorithm == "prefsqp"
    assert preset.options == explicit.options
    assert preset == explicit
