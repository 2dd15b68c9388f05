"""What a re-run replaced: ``replaced_runs.json`` from the history of a scratch repository, and
the results page's table of re-runs against hand-computed rows."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

import numpy as np
import pytest

from localpbo_core.sweep import write_run


def _git(root: Path, *args: str) -> str:
    return subprocess.run(
        ["git", "-C", str(root), *args], capture_output=True, text=True, check=True
    ).stdout.strip()


def _doc(natives: list[float], winners: list[int], final: float, seed: int = 0) -> dict:
    return {
        "schema": "localpbo/run/v1",
        "settings": {"algorithm": "turpbo", "problem": "hartmann6", "seed": seed},
        "candidates": [{"id": i, "native": [x], "value": 0.0} for i, x in enumerate(natives)],
        "answers": [
            {"duel_id": i, "first": i + 1, "second": 0, "winner": w} for i, w in enumerate(winners)
        ],
        "records": [{"best_seen": final, "cumulative": 10 * final}],
    }


def _commit(root: Path, message: str) -> str:
    _git(root, "add", "-A")
    _git(root, "-c", "user.name=t", "-c", "user.email=t@t", "commit", "-q", "-m", message)
    return _git(root, "rev-parse", "HEAD")


def test_replaced_runs_come_from_the_history(tmp_path: Path) -> None:
    """A run rewritten with a code block over a run of the same settings gets the old run's
    storing commit, shared candidates, answers and finals; a run rewritten with other settings,
    one only added and one that already says what it replaced get no entry."""
    from localpbo_core.experiments.replaced import replaced_runs

    root = tmp_path
    _git(root, "init", "-q")
    runs = root / "docs" / "results" / "s" / "runs"
    write_run(runs / "a.json.gz", _doc([0.1, 0.2, 0.3], [1, 0], 2.0))
    write_run(runs / "b.json.gz", _doc([0.1, 0.2], [1], 1.0))
    write_run(runs / "c.json.gz", _doc([0.5], [], 1.0))
    stored = _commit(root, "first runs")
    code = {"digest": "d", "algorithm_digest": "a", "commit": stored, "dirty": False}
    write_run(runs / "a.json.gz", {**_doc([0.1, 0.2, 0.35], [1, 1], 2.5), "code": code})
    write_run(runs / "b.json.gz", {**_doc([0.1, 0.2], [1], 1.0, seed=3), "code": code})
    write_run(runs / "c.json.gz", {**_doc([0.5], [], 1.0), "code": code, "replaced": {}})
    write_run(runs / "d.json.gz", {**_doc([0.5], [], 1.0), "code": code})
    _commit(root, "re-runs")
    doc = replaced_runs(root)
    assert list(doc["runs"]) == ["s/runs/a.json.gz"]
    block = doc["runs"]["s/runs/a.json.gz"]
    assert block.pop("algorithm_digest") is not None
    assert block == {
        "commit": stored,
        "stored_by_commit": True,
        "candidates": 3,
        "identical": 2,
        "first_gap": pytest.approx(0.05),
        "same_answers": False,
        "same_platform": None,
        "best_seen": 2.0,
        "cumulative": 20.0,
    }


def test_rerun_table_rows() -> None:
    """One row per group with re-runs: counts, commits, the largest first gap and the finals
    before and after over the re-run seeds only."""
    from localpbo_core.report import StoredRun, rerun_table

    def run(seed: int, final: float, replaced: dict | None) -> StoredRun:
        return StoredRun(
            spec="s",
            problem_label="hartmann6",
            algorithm_label="turpbo",
            variant="",
            seed=seed,
            within_model=False,
            settings={"algorithm": "turpbo"},
            best_seen=np.array([final]),
            cumulative=np.array([final]),
            optimizer_seconds=1.0,
            replaced=replaced,
        )

    def block(commit: str, identical: int, gap: float, answers: bool, before: float) -> dict:
        return {
            "commit": commit,
            "candidates": 5,
            "identical": identical,
            "first_gap": gap,
            "same_answers": answers,
            "best_seen": before,
        }

    runs = [
        run(0, 2.0, block("aaaaaaaaaaaaaaaa", 5, 0.0, True, 2.0)),
        run(1, 3.0, block("bbbbbbbbbbbbbbbb", 2, 1e-9, True, 1.0)),
        run(2, 9.0, None),
        run(3, 4.0, block("aaaaaaaaaaaaaaaa", 0, 0.5, False, 3.0)),
    ]
    lines = rerun_table(runs)
    assert lines[2] == (
        "| s | hartmann6 | turpbo | 3 | aaaaaaaaaa, bbbbbbbbbb | 1 | 2 | 0.5 | 2 ± 1 | 3 ± 1 |"
    )
    assert rerun_table([run(0, 1.0, None)]) == []


def test_committed_table_names_reruns() -> None:
    """``docs/results/replaced_runs.json`` names committed runs with a code block of their own,
    each counting the candidates of its re-run (every 25th entry: reading all takes long)."""
    from localpbo_core.experiments.replaced import OUTPUT, load_replaced
    from localpbo_core.provenance import ROOT
    from localpbo_core.sweep import read_run

    entries = sorted(load_replaced(ROOT / OUTPUT).items())
    assert len(entries) >= 1000
    for path, block in entries[::25]:
        doc = read_run(path)
        assert isinstance(doc.get("code"), dict) and "replaced" not in doc
        assert block["candidates"] == len(doc["candidates"]) >= block["identical"] >= 0
        assert json.dumps(block)  # plain JSON types
