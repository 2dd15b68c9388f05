"""What the re-runs stored before re-runs said so replaced.

``localpbo sweep --rerun-changed`` stores a re-run with a ``replaced`` block
(:func:`localpbo_core.provenance.replaced_block`): the code of the run it replaced, how many
leading candidates the two share bit for bit, whether their duels got the same answers and
the old final values. Re-runs committed before the sweep wrote that block lost the old run
from the folder, not from the repository's history: the commit that wrote a run's present
bytes over other bytes of the same path holds both.

``python -m localpbo_core.experiments.replaced`` writes ``docs/results/replaced_runs.json``:
``runs``, for every committed run under ``docs/results`` and ``docs/pending`` that carries a
``code`` block but no ``replaced`` block, and whose path held a run of the same settings
before, that run's :func:`~localpbo_core.provenance.replaced_block` (the old run's own code
block, or the commit that first stored its bytes with that commit's digests,
:mod:`localpbo_core.experiments.stored_code`). ``--check`` only compares the file with what it
would write (exit 1 if it differs). Needs the repository's git history.

The results page reads both (:func:`localpbo_core.report.rerun_table`).
"""

from __future__ import annotations

import gzip
import json
import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from localpbo_core.experiments.stored_code import (
    FOLDERS,
    _git,
    code_at,
    first_commits,
    history_table_main,
)
from localpbo_core.provenance import ROOT, replaced_block

SCHEMA = "localpbo/replaced-runs/v1"
REPLACED_TABLE = "replaced_runs.json"
"""The file's name in its results folder."""
OUTPUT = f"docs/results/{REPLACED_TABLE}"


def replaced_by_history(root: Path) -> dict[str, tuple[str, str]]:
    """``{path: (old blob, new blob)}``: for each committed run file (relative to ``root``)
    whose present bytes were written over other bytes of the same path, the bytes before."""
    present: dict[str, str] = {}
    for line in _git(root, "ls-files", "-s", "--", *FOLDERS).decode().splitlines():
        meta, path = line.split("\t", 1)
        if path.endswith(".json.gz") and "/runs/" in path:
            present[path] = meta.split()[1]
    log = _git(
        root,
        "log",
        "--diff-filter=M",
        "--raw",
        "--no-abbrev",
        "--no-renames",
        "--format=C %H",
        "--",
        *FOLDERS,
    )
    out: dict[str, tuple[str, str]] = {}
    for line in log.decode().splitlines():
        if not line.startswith(":"):
            continue
        meta, path = line.split("\t", 1)
        old, new = meta.split()[2:4]
        if present.get(path) == new and path not in out:
            out[path] = (old, new)
    return out


def _blob_doc(root: Path, blob: str) -> dict[str, Any]:
    from localpbo_core.sweep import decode_run

    return decode_run(gzip.decompress(_git(root, "cat-file", "blob", blob)), f"blob {blob}")


def replaced_runs(root: Path = ROOT) -> dict[str, Any]:
    """The document of the module docstring for the runs committed under ``root``."""
    first = first_commits(root)
    home = (root / OUTPUT).parent
    runs: dict[str, dict[str, Any]] = {}
    digests: dict[tuple[str, str], dict[str, Any]] = {}
    for rel, (old_blob, new_blob) in sorted(replaced_by_history(root).items()):
        new = _blob_doc(root, new_blob)
        if not isinstance(new.get("code"), dict) or "replaced" in new:
            continue
        old = _blob_doc(root, old_blob)
        if old.get("settings") != new.get("settings"):
            continue  # another run at the same path, not a re-run of this one
        algorithm = str(old["settings"]["algorithm"])
        code = old.get("code")
        if not isinstance(code, dict) and old_blob in first:
            commit = first[old_blob]
            if (commit, algorithm) not in digests:
                digests[commit, algorithm] = code_at(root, commit, [algorithm])
            code = {
                "commit": commit,
                "algorithm_digest": digests[commit, algorithm]["algorithms"][algorithm],
                "stored_by_commit": True,
            }
        block = replaced_block(old, new, code if isinstance(code, dict) else None)
        runs[os.path.relpath(root / rel, home)] = block
    return {"schema": SCHEMA, "runs": runs}


def load_replaced(table: Path) -> dict[Path, dict[str, Any]]:
    """``{resolved run path: replaced block}`` of a ``replaced_runs.json`` file; empty if the
    file does not exist."""
    if not table.is_file():
        return {}
    doc = json.loads(table.read_text())
    return {(table.parent / rel).resolve(): block for rel, block in doc["runs"].items()}


def main(argv: Sequence[str] | None = None) -> int:
    return history_table_main(
        argv,
        prog="python -m localpbo_core.experiments.replaced",
        description=f"Write {OUTPUT}: for each committed re-run without a replaced block, what "
        "the run it replaced was (from the repository's history).",
        output=OUTPUT,
        build=replaced_runs,
        summary=lambda doc: f"{len(doc['runs'])} re-runs",
    )


if __name__ == "__main__":
    raise SystemExit(main())
