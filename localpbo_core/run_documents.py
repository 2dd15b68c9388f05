"""Run documents: one finished run as JSON (schema ``localpbo/run/v1``), as ``localpbo bench``
writes it under ``runs/`` and sweeps store it (:mod:`localpbo_core.sweep`), and where such
files are found (:func:`run_files`)."""

from __future__ import annotations

import json
from collections.abc import Iterable
from pathlib import Path
from typing import Any

from localpbo_core.loop import RESULT_COLUMNS, RunTrace
from localpbo_core.settings import RunSettings, SettingError


def run_file_name(settings: RunSettings) -> str:
    """``<problem>_<algorithm>_seed<seed>.json``: one file per finished run."""
    return f"{settings.problem}_{settings.algorithm}_seed{settings.seed}.json"


def trace_document(settings: RunSettings, trace: RunTrace) -> dict[str, Any]:
    """One run as a JSON-ready document (schema ``localpbo/run/v1``): its settings, every
    candidate (native units and value), every accepted answer and every evaluation record."""
    return {
        "schema": "localpbo/run/v1",
        "settings": settings_document(settings),
        "candidates": [
            {"id": cid, "native": list(trace.native[cid]), "value": trace.values[cid]}
            for cid in sorted(trace.native)
        ],
        "answers": [
            {
                "duel_id": a.duel_id,
                "first": a.first,
                "second": a.second,
                "kind": a.kind.value,
                "winner": a.winner,
            }
            for a in trace.answers
        ],
        "records": [dict(zip(RESULT_COLUMNS, r.as_row(), strict=True)) for r in trace.records],
    }


def settings_document(settings: RunSettings) -> dict[str, Any]:
    """The fields of ``settings`` as stored with a run (JSON types: tuples become lists).
    ``tie_threshold`` and ``indifference`` appear only when > 0, so documents of runs without
    "can't tell" answers are unchanged."""
    doc: dict[str, Any] = {
        "algorithm": settings.algorithm,
        "problem": settings.problem,
        "seed": settings.seed,
        "budget": settings.budget,
        "initial_design": settings.initial_design,
        "noise_fraction": settings.noise_fraction,
        "optimizer_options": dict(settings.optimizer_options),
        "problem_options": dict(settings.problem_options),
    }
    if settings.tie_threshold > 0 or settings.indifference > 0:
        doc["tie_threshold"] = settings.tie_threshold
        doc["indifference"] = settings.indifference
    return dict(json.loads(json.dumps(doc, default=str)))


def write_trace(settings: RunSettings, trace: RunTrace, path: Path) -> None:
    """One run as JSON (:func:`trace_document`). Floats are written exactly (JSON's
    shortest round-trip representation)."""
    path.write_text(json.dumps(trace_document(settings, trace), default=str) + "\n")


def run_files(paths: Iterable[str | Path]) -> list[Path]:
    """Every run file under ``paths`` (folders searched for ``runs/*.json[.gz]``), sorted."""
    found: set[Path] = set()
    for p in map(Path, paths):
        if p.is_dir():
            for pattern in ("*.json.gz", "*.json"):
                found.update(q for q in p.rglob(pattern) if q.parent.name == "runs")
        elif p.is_file():
            found.add(p)
        else:
            raise SettingError("results", f"{p} does not exist")
    return sorted(found)
