"""Which code stored the runs that carry no code version of their own.

Runs stored before runs carried a ``code`` block (:mod:`localpbo_core.provenance`) say only
what they ran, not with which code. The repository's history says when each was stored: the
oldest commit that added the file's exact bytes (a run moved between folders keeps its
bytes, so the move does not count). That commit's sources bound the code that made the run
from above: a sweep runs before its results are committed, so the run was made by that commit's
code or an older one.

``python -m localpbo_core.experiments.stored_code`` writes ``docs/results/stored_code.json``:

* ``runs``: for every stored run under ``docs/results`` and ``docs/pending`` without a
  ``code`` block, its path (relative to the file's folder) and the commit that stored it (for
  a copy made by ``localpbo sweep --reuse``, the commit that stored its source);
* ``commits``: for each such commit, the digests :func:`localpbo_core.provenance.code_block`
  would have given there, computed from the commit's files with today's lists of sources
  (:data:`~localpbo_core.provenance.RUN_SOURCES`,
  :func:`~localpbo_core.provenance.algorithm_sources`): ``digest`` and one
  ``algorithm_digest`` per algorithm.

The report reads the file beside the runs (:func:`localpbo_core.report.load_runs`) and
judges those runs as it judges runs with a code block, marked as stored-by-commit. ``--check``
only compares the file with what it would write (exit 1 if it differs). Needs the
repository's git history (a shallow clone has too little of it).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
from collections.abc import Callable, Iterable, Sequence
from pathlib import Path
from typing import Any

from localpbo_core.provenance import (
    ALGORITHM_MODULES,
    ROOT,
    RUN_SOURCES,
    algorithm_sources,
    digest_of,
)

SCHEMA = "localpbo/stored-code/v1"
FOLDERS = ("docs/results", "docs/pending")
"""The folders of the committed runs, relative to the repository's root."""
OUTPUT = "docs/results/stored_code.json"


def _git(root: Path, *args: str, data: bytes | None = None) -> bytes:
    return subprocess.run(
        ["git", "-C", str(root), *args], input=data, capture_output=True, check=True
    ).stdout


def first_commits(root: Path) -> dict[str, str]:
    """``{blob: commit}``: for each file content ever committed, the oldest commit that added
    or rewrote a file with those bytes anywhere."""
    first: dict[str, str] = {}
    log = _git(
        root, "log", "--diff-filter=AM", "--raw", "--no-abbrev", "--no-renames", "--format=C %H"
    )
    commit = ""
    for line in log.decode().splitlines():
        if line.startswith("C "):
            commit = line[2:]
        elif line.startswith(":"):
            blob = line.split()[3]  # the new side of an added or modified file
            first[blob] = commit  # the log runs newest first: the last one seen is oldest
    return first


def storing_commits(
    root: Path, paths: Sequence[str], first: dict[str, str] | None = None
) -> dict[str, str]:
    """``{path: commit}``: for each committed file in ``paths`` (relative to ``root``), the
    oldest commit that added or rewrote a file with the same bytes anywhere (module
    docstring); ``first``: :func:`first_commits`, when the caller has it."""
    first = first_commits(root) if first is None else first
    out: dict[str, str] = {}
    for line in _git(root, "ls-files", "-s", "--", *paths).decode().splitlines():
        meta, path = line.split("\t", 1)
        blob = meta.split()[1]
        if blob in first:
            out[path] = first[blob]
    return out


def code_at(root: Path, commit: str, algorithms: Iterable[str]) -> dict[str, Any]:
    """The digests of :func:`localpbo_core.provenance.code_block` for the files of
    ``commit``: ``{"digest": ..., "algorithms": {algorithm: algorithm_digest}}``."""
    entries = set(RUN_SOURCES)
    for algorithm in algorithms:
        entries.update(algorithm_sources(algorithm))
    listing = _git(root, "ls-tree", "-r", "--full-tree", commit, "--", *sorted(entries))
    blobs: dict[str, str] = {}
    for line in listing.decode().splitlines():
        meta, path = line.split("\t", 1)
        if path.endswith(".py") and "__pycache__" not in path:
            blobs[path] = meta.split()[2]
    batch = _git(
        root, "cat-file", "--batch", data="".join(f"{b}\n" for b in blobs.values()).encode()
    )
    contents: dict[str, bytes] = {}
    pos = 0
    for path in blobs:
        header_end = batch.index(b"\n", pos)
        size = int(batch[pos:header_end].split()[2])
        contents[path] = batch[header_end + 1 : header_end + 1 + size]
        pos = header_end + 1 + size + 1

    def digest(sources: Iterable[str]) -> str:
        chosen = [
            (path, data)
            for path, data in contents.items()
            if any(path == e or path.startswith(e.rstrip("/") + "/") for e in sources)
        ]
        return digest_of(chosen)

    return {
        "digest": digest(RUN_SOURCES),
        "algorithms": {a: digest(algorithm_sources(a)) for a in sorted(algorithms)},
    }


def _blob_at(root: Path, commit: str, path: str) -> str:
    """The blob of ``path`` at ``commit`` (empty when the commit has no such file)."""
    done = subprocess.run(
        ["git", "-C", str(root), "rev-parse", "--verify", "--quiet", f"{commit}:{path}"],
        capture_output=True,
    )
    return done.stdout.decode().strip() if done.returncode == 0 else ""


def _has_code(path: Path) -> tuple[bool, str, str]:
    """Whether the run carries a code block, its algorithm, and the run it was copied from."""
    from localpbo_core.sweep import read_run

    doc = read_run(path)
    reused = str((doc.get("run") or {}).get("reused_from", ""))
    return isinstance(doc.get("code"), dict), str(doc["settings"]["algorithm"]), reused


def stored_code(root: Path = ROOT) -> dict[str, Any]:
    """The document of the module docstring for the runs committed under ``root``."""
    from localpbo_core.run_documents import run_files

    folders = [root / f for f in FOLDERS if (root / f).is_dir()]
    files = [p.relative_to(root).as_posix() for p in run_files(folders)]
    first = first_commits(root)
    commits = storing_commits(root, files, first)
    tracked = set(_git(root, "ls-files", "--", *FOLDERS).decode().splitlines())
    files = [f for f in files if f in tracked]
    home = (root / OUTPUT).parent
    runs: dict[str, str] = {}
    algorithms: dict[str, set[str]] = {}
    for rel in files:
        has_code, algorithm, reused_from = _has_code(root / rel)
        if has_code:
            continue
        if reused_from and rel in commits:
            # a copy (localpbo sweep --reuse) was made by the code that made its source as it
            # was when the copy was stored (the source may have been re-run since)
            spec, run_id = reused_from.split("/", 1)
            folder = Path(rel).parent.parent.parent
            source = (folder / spec / "runs" / f"{run_id}.json.gz").as_posix()
            copied = _blob_at(root, commits[rel], source)
            if copied in first:
                commits[rel] = first[copied]
        if rel not in commits:
            continue
        runs[os.path.relpath(root / rel, home)] = commits[rel]
        algorithms.setdefault(commits[rel], set()).add(algorithm)
    known = set(ALGORITHM_MODULES)
    return {
        "schema": SCHEMA,
        "commits": {c: code_at(root, c, sorted(a & known)) for c, a in sorted(algorithms.items())},
        "runs": dict(sorted(runs.items())),
    }


def dumps(doc: dict[str, Any]) -> str:
    """The file's text (sorted keys, one entry per line)."""
    return json.dumps(doc, indent=1, sort_keys=True) + "\n"


def history_table_main(
    argv: Sequence[str] | None,
    *,
    prog: str,
    description: str,
    output: str,
    build: Callable[[Path], dict[str, Any]],
    summary: Callable[[dict[str, Any]], str],
) -> int:
    """The command line of a table the repository's history determines (this module's,
    :mod:`localpbo_core.experiments.replaced`): write ``output`` (relative to the checkout)
    from ``build(ROOT)`` and print ``summary`` of it, or with ``--check`` only compare (exit 1
    if the file differs)."""
    parser = argparse.ArgumentParser(prog=prog, description=description)
    parser.add_argument(
        "--check", action="store_true", help="compare with the committed file; write nothing"
    )
    args = parser.parse_args(argv)
    text = dumps(build(ROOT))
    path = ROOT / output
    if args.check:
        same = path.is_file() and path.read_text() == text
        print(f"{output}: {'up to date' if same else 'differs from what the history says'}")
        return 0 if same else 1
    path.write_text(text)
    print(f"{output}: {summary(json.loads(text))}")
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    return history_table_main(
        argv,
        prog="python -m localpbo_core.experiments.stored_code",
        description=f"Write {OUTPUT}: the commit that stored each committed run without a "
        "code version, and that commit's code digests.",
        output=OUTPUT,
        build=stored_code,
        summary=lambda doc: f"{len(doc['runs'])} runs, {len(doc['commits'])} commits",
    )


if __name__ == "__main__":
    raise SystemExit(main())
