"""``python -m localpbo_core.experiments.drift``: where a re-run departs from a stored run."""

from __future__ import annotations

import subprocess
from pathlib import Path

import pytest

from localpbo_core.experiments.drift import compare, table
from localpbo_core.provenance import code_block, platform_changes


def _git(*args: str) -> str:
    """``git ARGS`` in the checkout, its output stripped."""
    from localpbo_core.provenance import ROOT

    return subprocess.run(
        ["git", "-C", str(ROOT), *args], capture_output=True, text=True, check=True
    ).stdout.strip()


def _doc(natives: list[list[float]], final: float, code: dict | None = None) -> dict:
    doc = {
        "run": {"run_id": "hartmann6__hbei__seed1"},
        "settings": {"algorithm": "hbei"},
        "candidates": [{"id": i, "native": x, "value": 0.0} for i, x in enumerate(natives)],
        "records": [{"best_seen": final}],
    }
    if code is not None:
        doc["code"] = code
    return doc


def test_first_difference_and_finals() -> None:
    stored = _doc([[0.1, 0.2], [0.3, 0.4], [0.5, 0.6]], 2.966)
    now = _doc([[0.1, 0.2], [0.3, 0.4 + 1e-12], [0.9, 0.9]], 2.942)
    d = compare(stored, now)
    assert (d.identical, d.candidates, d.stored_final, d.now_final) == (1, 3, 2.966, 2.942)
    assert abs(d.first_gap - 1e-12) < 1e-15
    assert (d.stored_code, d.algorithm_changed) == ("none", "unknown")
    same = compare(stored, stored)
    assert (same.identical, same.first_gap) == (3, 0.0)
    assert table([d])[-1] == (
        "| hartmann6__hbei__seed1 | none | unknown | 1 of 3 | 1e-12 | 2.966 | 2.942 | unknown |"
    )


def test_platform_differences_are_named() -> None:
    """A re-run on another CPU kernel level or library version says which fields differ;
    the same platform reads "same"."""
    from localpbo_core.provenance import platform_block

    here = {**platform_block(), "environment": {}}
    other = "AVX512" if here["cpu_capability"] != "AVX512" else "AVX2"
    elsewhere = {
        **here,
        "cpu_capability": other,
        "libraries": {**here["libraries"], "torch": "0.0"},
        "environment": {"MKL_CBWR": "COMPATIBLE"},
    }
    stored = {**_doc([[0.1]], 1.0), "platform": elsewhere}
    now = {**_doc([[0.1]], 1.0), "platform": here}
    assert compare(stored, now).platform == "; ".join(
        [
            f"cpu_capability: {other} -> {here['cpu_capability']}",
            "environment.MKL_CBWR: COMPATIBLE -> -",
            f"libraries.torch: 0.0 -> {here['libraries']['torch']}",
        ]
    )
    assert compare(now, now).platform == "same"
    assert platform_changes(here, here) == []
    assert compare(_doc([[0.1]], 1.0), now).platform == "unknown"


def test_stored_code_is_judged_against_today() -> None:
    today = dict(code_block("hbei"))
    older = {**today, "algorithm_digest": "0" * 16, "commit": "abcdef1234567", "dirty": True}
    x = [[0.5]]
    assert compare(_doc(x, 1.0, today), _doc(x, 1.0)).algorithm_changed == "no"
    changed = compare(_doc(x, 1.0, older), _doc(x, 1.0))
    assert (changed.stored_code, changed.algorithm_changed) == ("abcdef1234+dirty", "yes")


def test_committed_storing_commits_name_stored_runs_and_their_digests() -> None:
    """``docs/results/stored_code.json`` names committed runs without a code block, each
    with a commit of this history that added or rewrote exactly its bytes (a copy: its
    source's), and that commit's digests as
    :func:`~localpbo_core.experiments.stored_code.code_at` computes them."""
    import json

    from localpbo_core.experiments.stored_code import FOLDERS, code_at
    from localpbo_core.provenance import ROOT, stored_by_commit
    from localpbo_core.sweep import read_run

    table = ROOT / "docs" / "results" / "stored_code.json"
    runs = stored_by_commit(table)
    # a run without a code block of its own is dated by the table: every 100th stored run
    # (all of them take minutes to read)
    stored = sorted(
        path.resolve() for folder in FOLDERS for path in (ROOT / folder).glob("*/runs/*.json.gz")
    )
    sample = stored[::100]
    assert len(sample) >= 10
    for path in sample:
        assert "code" in read_run(path) or path in runs, path
    doc = json.loads(table.read_text())
    if _git("rev-parse", "--is-shallow-repository") == "true":
        assert all(path.is_file() for path in runs)
        pytest.skip("a shallow clone holds too little history to check the storing commits")
    for i, (path, (commit, _digests)) in enumerate(sorted(runs.items())):
        assert path.is_file(), path
        if i % 250:
            continue
        assert "code" not in read_run(path)
        rel = path.relative_to(ROOT).as_posix()
        blob = _git("rev-parse", f"HEAD:{rel}")
        added = _git("show", "--raw", "--no-abbrev", "--format=", commit)
        copied = "reused_from" in read_run(path)["run"]
        assert copied or any(
            line.split()[3] == blob and line.split()[4] in ("A", "M") for line in added.splitlines()
        )
    for commit in sorted(doc["commits"])[:2]:
        recorded = doc["commits"][commit]
        assert code_at(ROOT, commit, sorted(recorded["algorithms"])) == recorded


def test_equivalent_code_records_name_committed_runs() -> None:
    """Each re-run recorded in ``docs/results/equivalent_code.json`` names a committed run of
    its algorithm and counts at most its candidates."""
    import json

    from localpbo_core.provenance import ROOT
    from localpbo_core.sweep import read_run

    table = ROOT / "docs" / "results" / "equivalent_code.json"
    for entry in json.loads(table.read_text()):
        doc = read_run(ROOT / entry["run"])
        assert doc["settings"]["algorithm"] == entry["algorithm"]
        assert entry["candidates"] == len(doc["candidates"])
        assert 0 <= entry["identical"] <= entry["candidates"]
        assert 0 <= entry["stored_identical"] <= entry["candidates"]


def test_every_optimizer_module_belongs_to_an_algorithm_digest() -> None:
    """A module of ``localpbo_core/optimizers`` that no algorithm's digest covers could change
    stored runs unnoticed: each is shared by all or listed for an algorithm."""
    from localpbo_core.provenance import (
        ALGORITHM_MODULES,
        ROOT,
        SHARED_ALGORITHM_SOURCES,
    )

    folder = ROOT / "localpbo_core" / "optimizers"
    covered = {m for modules in ALGORITHM_MODULES.values() for m in modules}
    covered |= {
        Path(s).name for s in SHARED_ALGORITHM_SOURCES if s.startswith("localpbo_core/optimizers/")
    }
    missing = sorted(p.name for p in folder.glob("*.py") if p.name not in covered | {"__init__.py"})
    assert missing == []


def test_a_copy_is_dated_by_its_source_as_it_was_copied() -> None:
    """A copy (``sweep --reuse``) whose source was re-run since keeps the storing commit of the
    source's bytes it copied, not the re-run's (its trace is the old one)."""
    from localpbo_core.provenance import ROOT, stored_by_commit
    from localpbo_core.sweep import read_run

    if _git("rev-parse", "--is-shallow-repository") == "true":
        pytest.skip("a shallow clone holds too little history")
    runs = stored_by_commit(ROOT / "docs" / "results" / "stored_code.json")
    copy = (
        ROOT
        / "docs/results/ablation_prefsqp_causes/runs/hartmann6__prefsqp__noise0.1__seed0.json.gz"
    )
    source = "docs/results/beyond_local_steps/runs/hartmann6__prefsqp__seed0.json.gz"
    assert "code" in read_run(ROOT / source)  # re-run with today's code
    assert "code" not in read_run(copy)  # copied before the re-run, from a run without one
    assert read_run(copy)["run"]["reused_from"] == "beyond_local_steps/hartmann6__prefsqp__seed0"
    commit, _ = runs[copy]
    rel = copy.relative_to(ROOT).as_posix()
    copied_at = _git("log", "--diff-filter=A", "--format=%H", "--", rel).splitlines()[-1]
    old_blob = _git("rev-parse", f"{copied_at}:{source}")
    added = _git("show", "--raw", "--no-abbrev", "--format=", commit)
    assert any(line.split()[3] == old_blob for line in added.splitlines())
    assert old_blob != _git("rev-parse", f"HEAD:{source}")


def test_an_algorithm_digest_covers_the_optimizer_modules_it_imports() -> None:
    """Each module an algorithm's own modules import from ``localpbo_core.optimizers``
    (directly or through another of them) is in its digest: a change to it can change the
    algorithm's runs."""
    import ast

    from localpbo_core.provenance import ALGORITHM_MODULES, ROOT, SHARED_ALGORITHM_SOURCES

    folder = ROOT / "localpbo_core" / "optimizers"
    shared = {Path(s).name for s in SHARED_ALGORITHM_SOURCES}

    def imported(module: str) -> set[str]:
        tree = ast.parse((folder / module).read_text())
        prefix = "localpbo_core.optimizers."
        return {
            node.module.removeprefix(prefix) + ".py"
            for node in ast.walk(tree)
            if isinstance(node, ast.ImportFrom)
            and node.module is not None
            and node.module.startswith(prefix)
        }

    uncovered = {}
    for algorithm, own in ALGORITHM_MODULES.items():
        seen, todo = set(), list(own)
        while todo:
            module = todo.pop()
            if module in seen or module in shared:
                continue
            seen.add(module)
            todo += imported(module)
        if missing := sorted(seen - set(own)):
            uncovered[algorithm] = missing
    assert uncovered == {}


def test_a_why_record_names_both_digests_of_the_old_code() -> None:
    """When an algorithm's list of files grew, the old commit's digest over today's list
    differs from the one its runs stored; ``--record`` links both to today's digest, so runs
    dated by either (their own block, or ``stored_code.json``) read as the same behaviour."""
    from localpbo_core.experiments.drift import Why, _block_digest

    w = Why("r", "hybrid", "c0ffee", "new-list", "today", 62, 62, 62, 0.0, "old-list")
    assert [(e["from"], e["to"]) for e in w.records("p")] == [
        ("new-list", "today"),
        ("old-list", "today"),
    ]
    same = Why("r", "hybrid", "c0ffee", "d", "today", 62, 62, 62, 0.0, "d")
    assert [e["from"] for e in same.records("p")] == ["d"]
    block = {"commit": "c0ffee", "dirty": False, "algorithm_digest": "old-list"}
    assert _block_digest({"code": block}, "c0ffee") == "old-list"
    assert _block_digest({"code": block}, "beef") is None
    assert _block_digest({"code": {**block, "dirty": True}}, "c0ffee") is None
    assert _block_digest({}, "c0ffee") is None
