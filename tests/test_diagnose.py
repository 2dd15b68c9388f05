"""Duel diagnostics of stored runs, checked on a hand-made run against counts by hand."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pytest

from localpbo_core.experiments.diagnose import diagnose, diagnose_run, main, table
from tests.fabricated import run_document


@dataclass(frozen=True)
class Box:
    """A 2-D problem on the native box [-5, 5]^2 with value range 10."""

    name: str = "box"
    dim: int = 2
    value_range: float = 10.0

    def to_native(self, theta: np.ndarray) -> np.ndarray:
        return -5.0 + 10.0 * np.asarray(theta)


def _doc() -> dict:
    # values 0, 1, 5, -2, 3; ids 0-1 are the initial design
    natives = [[0, 0], [1, 1], [-5, 4.95], [2, 5], [-4.89, 0]]
    values = [0.0, 1.0, 5.0, -2.0, 3.0]
    answers = [
        {"duel_id": 0, "first": 1, "second": 0, "kind": "decisive", "winner": 1},  # newer wins
        {"duel_id": 1, "first": 2, "second": 1, "kind": "decisive", "winner": 1},  # flip, lost
        {"duel_id": 2, "first": 3, "second": 1, "kind": "indifferent"},  # not counted
        {"duel_id": 3, "first": 3, "second": 1, "kind": "decisive", "winner": 1},  # lost
        {"duel_id": 4, "first": 4, "second": 1, "kind": "decisive", "winner": 4},  # won
    ]
    return run_document("turpbo", 3, natives, values, answers)


def test_counts_match_a_hand_count() -> None:
    d = diagnose_run(_doc(), Box())
    assert (d.problem, d.algorithm, d.seed, d.dim, d.duels) == ("box", "turpbo", 3, 2, 4)
    assert d.flipped == pytest.approx(1 / 4)  # duel 1: value 1 beat value 5
    # gaps 1, 4, 3, 2 -> median 2.5; sigma = 0.1 * 10
    assert d.median_gap_sigma == pytest.approx(2.5)
    assert d.proposals_mean == pytest.approx((5.0 - 2.0 + 3.0) / 3)
    # proposed coordinates: (-5, 4.95) both at a bound (within 0.1), (2, 5) one, (-4.89, 0) none
    assert d.at_bound == pytest.approx(3 / 6)
    assert d.newer_won == pytest.approx(2 / 4)
    # true values newer vs older: 1 > 0, 5 > 1, -2 < 1, 3 > 1
    assert d.newer_better == pytest.approx(3 / 4)
    # unit-cube steps |(0.1, 0.1)|, |(-0.6, 0.395)|, |(0.1, 0.4)|, |(-0.589, -0.1)|: the
    # median is the mean of the middle two
    middle = (math.hypot(0.1, 0.4) + math.hypot(-0.589, -0.1)) / 2
    assert d.median_step == pytest.approx(middle)
    assert d.longest_lost_streak == 2


def test_older_files_without_kind_count_as_decisive() -> None:
    doc = _doc()
    doc["answers"] = [{k: v for k, v in a.items() if k != "kind"} for a in doc["answers"][:2]]
    d = diagnose_run(doc, Box())
    assert d.duels == 2 and d.flipped == pytest.approx(0.5)


def test_table_and_command_on_stored_runs(tmp_path, capsys) -> None:
    from localpbo_core.experiments.spec import load_spec
    from localpbo_core.sweep import execute_run, run_path, write_run

    for plan in load_spec("tiny").runs():  # Sobol and TuRPBO on Hartmann 6, 8 evaluations
        if plan.settings.seed == 0:
            write_run(run_path(tmp_path, plan), execute_run(plan))
    ds = diagnose([tmp_path])
    assert [d.algorithm for d in ds] == ["sobol", "turpbo"]
    assert all(d.duels == 7 and 0.0 <= d.flipped <= 1.0 for d in ds)
    lines = table(ds, {"hartmann6": 0.25})
    assert len(lines) == 3 and lines[1].split()[:3] == ["hartmann6", "sobol", "1"]
    assert main([str(tmp_path), "--algorithms", "turpbo"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert len(out) == 2 and out[1].split()[1] == "turpbo"
    assert not math.isnan(float(out[1].split()[6]))  # the uniform reference was computed
