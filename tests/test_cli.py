"""The ``localpbo`` command (localpbo_core.cli)."""

from __future__ import annotations

import csv

import numpy as np
import pytest
import torch

from localpbo_core.cli import main
from localpbo_core.loop import RESULT_COLUMNS


@pytest.fixture(autouse=True)
def _restore_torch_threads():
    """``--torch-threads`` sets a process-wide value: restore it after each test."""
    n = torch.get_num_threads()
    yield
    torch.set_num_threads(n)


def _rows(path):
    with path.open() as fh:
        return list(csv.DictReader(fh))


def test_bench_writes_results_summary_and_plot(tmp_path, capsys) -> None:
    out = tmp_path / "run"
    code = main(
        [
            "bench",
            "--problem",
            "hartmann6",
            "--algorithm",
            "sobol,turpbo",
            "--seeds",
            "0,1",
            "--budget",
            "6",
            "--out",
            str(out),
            "--no-progress",
            "--torch-threads",
            "1",
        ]
    )
    assert code == 0
    rows = _rows(out / "results.csv")
    assert list(rows[0]) == list(RESULT_COLUMNS)
    assert len(rows) == 2 * 2 * 6
    for alg in ("sobol", "turpbo"):
        for seed in ("0", "1"):
            run = [r for r in rows if r["algorithm"] == alg and r["seed"] == seed]
            assert [int(r["evaluation"]) for r in run] == list(range(1, 7))
            f = np.array([float(r["f_true"]) for r in run])
            best = np.array([float(r["best_seen"]) for r in run])
            np.testing.assert_allclose(best, np.maximum.accumulate(f))
    # same seed -> same shared initial design for both algorithms
    first = {(r["algorithm"], r["seed"]): r["f_true"] for r in rows if r["evaluation"] == "1"}
    assert first[("sobol", "0")] == first[("turpbo", "0")]
    summary = _rows(out / "summary.csv")
    assert [s["algorithm"] for s in summary] == ["sobol", "turpbo"]
    finals = [
        float(r["best_seen"]) for r in rows if r["algorithm"] == "sobol" and r["evaluation"] == "6"
    ]
    assert float(summary[0]["best_seen_mean"]) == pytest.approx(np.mean(finals))
    assert (out / "best_seen.png").stat().st_size > 1000
    printed = capsys.readouterr().out
    assert "results.csv" in printed and "turpbo" in printed


def test_budget_counts_every_evaluation_on_hartmann6(tmp_path) -> None:
    out = tmp_path / "h6"
    assert (
        main(
            [
                "bench",
                "--problem",
                "hartmann6",
                "--algorithm",
                "sobol",
                "--seeds",
                "0-1",
                "--budget",
                "62",
                "--out",
                str(out),
                "--no-progress",
            ]
        )
        == 0
    )
    assert len(_rows(out / "results.csv")) == 2 * 62


@pytest.mark.parametrize(
    ("args", "needle"),
    [
        (["--algorithm", "nope"], "--algorithm"),
        (["--problem", "nope"], "problem"),
        (["--budget", "3", "--initial-design", "4"], "budget"),
        (["--option", "colour=red"], "colour"),
        (["--option", "sobol.acquisition=qeubo"], "acquisition"),
        (["--option", "turpbo.acquisition=nope"], "acquisition"),
        (["--option", "turpbo.warm_start=[0.5, 0.5, 0.5, 0.5, 0.5, nan]"], "warm_start"),
        (["--option", "turpbo.warm_start=[0.5, 0.5]"], "warm_start"),
        (["--noise", "-1"], "--noise"),
        (["--seeds", "a"], ""),
        (["--batch-size", "0"], "batch_size"),
        (["--indifference", "0.1"], "--indifference"),
        (["--tie-threshold", "-0.5"], "--tie-threshold"),
    ],
)
def test_bad_options_fail_at_start_naming_the_option(tmp_path, capsys, args, needle) -> None:
    base = {"--problem": "hartmann6", "--algorithm": "sobol,turpbo", "--budget": "10"}
    argv = ["bench", "--out", str(tmp_path / "x"), "--no-progress"]
    for key, value in base.items():
        if key not in args:
            argv += [key, value]
    with pytest.raises(SystemExit) as exc:
        main(argv + args)
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert needle in err
    assert not (tmp_path / "x" / "results.csv").exists()


def test_help_explains_every_option(capsys) -> None:
    with pytest.raises(SystemExit):
        main(["bench", "--help"])
    text = capsys.readouterr().out
    for opt in (
        "--problem",
        "--algorithm",
        "--seeds",
        "--budget",
        "--out",
        "--initial-design",
        "--noise",
        "--batch-size",
        "--option",
        "--torch-threads",
        "--tie-threshold",
        "--indifference",
    ):
        assert opt in text
    with pytest.raises(SystemExit):
        main(["demo", "--help"])
    assert "--out" in capsys.readouterr().out


def test_tie_threshold_flag_alone_is_the_default_for_a_person() -> None:
    from localpbo_core.cli import _build_parser
    from localpbo_core.settings import DEFAULT_TIE_THRESHOLD

    parser = _build_parser()
    base = ["bench", "--problem", "hartmann6", "--algorithm", "sobol", "--out", "x"]
    assert parser.parse_args(base).tie_threshold == 0.0
    assert parser.parse_args([*base, "--tie-threshold"]).tie_threshold == DEFAULT_TIE_THRESHOLD
    assert parser.parse_args([*base, "--tie-threshold", "1"]).tie_threshold == 1.0


@pytest.mark.slow
def test_demo_runs_and_reports_where_results_went(tmp_path, capsys) -> None:
    out = tmp_path / "demo"
    assert main(["demo", "--out", str(out), "--torch-threads", "1"]) == 0
    rows = _rows(out / "results.csv")
    assert len(rows) == 2 * 40
    assert str(out / "results.csv") in capsys.readouterr().out


@pytest.mark.parametrize(("problem", "budget"), [("hartmann6", 12), ("swimmer", 5)])
def test_bench_runs_every_algorithm(tmp_path, problem, budget) -> None:
    """``localpbo bench`` runs every registered algorithm on Hartmann 6 and on a
    MuJoCo task (short budgets; the full runs are in README)."""
    from collections import Counter

    from localpbo_core.optimizers import available_optimizers

    names = available_optimizers()
    out = tmp_path / problem
    args = ["bench", "--problem", problem, "--algorithm", ",".join(names), "--seeds", "0"]
    assert main([*args, "--budget", str(budget), "--out", str(out), "--no-progress"]) == 0
    per_alg = Counter(r["algorithm"] for r in _rows(out / "results.csv"))
    assert per_alg == dict.fromkeys(names, budget)
