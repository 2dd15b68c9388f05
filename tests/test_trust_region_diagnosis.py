"""``python -m localpbo_core.experiments.trust_region``: TuRPBO's recorded region history
against an independent replay of Alg. TurPBO's rules, the table, and refused selections."""

from __future__ import annotations

import dataclasses
import math

import pytest

from localpbo_core.experiments import load_spec
from localpbo_core.experiments.trust_region import main, run_region, table, turpbo_runs
from localpbo_core.optimizers.trust_region import TrustRegionState
from localpbo_core.settings import SettingError


@pytest.fixture(scope="module")
def region_run():
    (plan,) = turpbo_runs(load_spec("tiny"), algorithms=["turpbo"], seeds=[0])
    plan = dataclasses.replace(plan, settings=plan.settings.replace(budget=40))
    return run_region(plan)


def test_history_follows_the_rules_of_alg_turpbo(region_run) -> None:
    steps = region_run.steps
    assert len(steps) == 40 - 2  # q = 1: one iteration per evaluation after the design
    assert any(s.success for s in steps) and not all(s.success for s in steps)
    assert len({s.length for s in steps}) > 1  # the region changed: before/after differ
    replay = TrustRegionState(dim=6)
    for step in steps:
        assert math.isclose(step.length, replay.length)
        assert step.event is replay.update(step.success)


def test_table_shares(region_run) -> None:
    head, row = table([region_run])
    assert head.split()[:4] == ["problem", "algorithm", "seeds", "best"]
    cells = row.split()
    assert cells[:3] == ["hartmann6", "turpbo", "1"]
    assert math.isclose(float(cells[3]), region_run.best_seen, rel_tol=1e-3)
    wide, mid, narrow = (float(c) for c in cells[4:7])
    lengths = [s.length for s in region_run.steps]
    assert math.isclose(wide, sum(v >= 0.8 for v in lengths) / len(lengths), abs_tol=0.005)
    assert math.isclose(mid, sum(v == 0.4 for v in lengths) / len(lengths), abs_tol=0.005)
    assert math.isclose(narrow, sum(v <= 0.2 for v in lengths) / len(lengths), abs_tol=0.005)
    wins = [s.success for s in region_run.steps if s.length >= 0.8]
    assert math.isclose(float(cells[7]), sum(wins) / len(wins), abs_tol=0.005)


def test_only_turpbo_runs_are_taken(capsys) -> None:
    with pytest.raises(SettingError) as info:
        turpbo_runs(load_spec("tiny"))
    assert info.value.field == "--algorithms" and "sobol" in info.value.reason
    with pytest.raises(SystemExit) as exc:
        main(["tiny", "--algorithms", "sobol"])
    assert exc.value.code == 2 and "--algorithms: " in capsys.readouterr().err


def test_command_prints_the_table(capsys) -> None:
    assert main(["tiny", "--algorithms", "turpbo", "--seeds", "0-1"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[0].split()[0] == "problem" and lines[1].split()[:3] == ["hartmann6", "turpbo", "2"]
