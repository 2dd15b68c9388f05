"""Re-run stored runs with the code at hand and show where they drift from what was stored.

``python -m localpbo_core.experiments.drift RUN_FILE...`` rebuilds each stored run's plan from
its spec (``run.spec``, ``run.run_id``), runs it in-process (as ``localpbo sweep
--in-process`` does) and prints per run: the code version stored with it (``code`` block,
:mod:`localpbo_core.provenance`; "none" for runs stored before runs carried one), whether its
algorithm's sources changed since, how many leading candidates are bit-identical, the largest
coordinate difference at the first candidate that differs, the final best-seen stored
and now, and what differs between the stored run's ``platform`` block and this machine's
(:func:`localpbo_core.provenance.platform_block`: CPU, torch's kernel level and threads,
library versions; "unknown" for runs stored without one). Nothing is written.

``--why`` tells drift by code from drift by machine: it also re-runs each stored run with the
code of the commit that made it (the run's ``code.commit``, or for runs stored without one the
commit that stored it, :mod:`localpbo_core.experiments.stored_code`), on this machine, from a
``git archive`` of that commit run through its own ``localpbo sweep --in-process``. Then

* stored against that commit here: what the *machine* changes (same code, other machine);
* that commit here against today's code here: what the *code* changes (same machine).

Floating-point sums depend on the machine's vector units and libraries, so a run made
elsewhere may part from its re-run at the last bit of some candidate and, through the
duels' noise draws and the model's refits, end elsewhere. ``--record FILE`` adds each
``--why`` result to a JSON list (``docs/results/equivalent_code.json`` for the committed
runs): the algorithm, the old and today's ``algorithm_digest``, and how many candidates the two
codes share on this machine. A run whose two codes agree on every candidate shows that the
old code's changes did not change that run's behaviour
(:func:`localpbo_core.report.code_state` reads the file).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from localpbo_core.provenance import identical_candidates, platform_changes


@dataclass(frozen=True)
class Drift:
    """A stored run against its re-run (module docstring)."""

    run_id: str
    stored_code: str
    algorithm_changed: str
    identical: int
    candidates: int
    first_gap: float
    stored_final: float
    now_final: float
    platform: str = "unknown"
    """"same" when the stored run's ``platform`` block equals the re-run's, else what differs
    (:func:`localpbo_core.provenance.platform_changes`); "unknown" for runs stored without one."""


def rerun(doc: dict[str, Any]) -> dict[str, Any]:
    """The document ``localpbo sweep`` would store for ``doc``'s plan today."""
    from localpbo_core.experiments import load_spec
    from localpbo_core.sweep import execute_run

    meta = doc["run"]
    plan = next(p for p in load_spec(meta["spec"]).runs() if p.run_id == meta["run_id"])
    return execute_run(plan)


def making_commit(doc: dict[str, Any], path: Path) -> str | None:
    """The commit whose code made the stored run: its ``code.commit``, else the commit that
    stored the file (``docs/results/stored_code.json``)."""
    code = doc.get("code")
    if isinstance(code, dict) and code.get("commit") and not code.get("dirty"):
        return str(code["commit"])
    from localpbo_core.provenance import ROOT, stored_by_commit

    table = ROOT / "docs" / "results" / "stored_code.json"
    found = stored_by_commit(table).get(path.resolve())
    return None if found is None else found[0]


ARCHIVED = ("localpbo_core", "localpbo_msgs_py", "sims", "ros_ws/src")
"""What a re-run with an older commit takes from it (the code, not the stored results)."""
PACKAGE_FOLDERS = {
    "localpbo_sims": "sims",
    "localpbo_ros": "ros_ws/src/localpbo_ros/localpbo_ros",
    "localpbo_examples": "ros_ws/src/localpbo_examples/localpbo_examples",
}
"""Import names whose folder has another name (``setup.py``'s ``package_dir``)."""


def rerun_at(commit: str, doc: dict[str, Any]) -> dict[str, Any]:
    """``doc``'s run made again by the code of ``commit`` on this machine: a ``git archive``
    of it in a temporary folder, its own ``localpbo sweep --in-process`` on that run alone."""
    from localpbo_core.provenance import ROOT
    from localpbo_core.sweep import read_run

    meta = doc["run"]
    with tempfile.TemporaryDirectory(prefix="localpbo-drift-") as tmp:
        tree = Path(tmp) / "tree"
        tree.mkdir()
        archive = subprocess.run(
            ["git", "-C", str(ROOT), "archive", commit, *ARCHIVED],
            capture_output=True,
            check=True,
        ).stdout
        subprocess.run(["tar", "-x", "-C", str(tree)], input=archive, check=True)
        for name, folder in PACKAGE_FOLDERS.items():
            if (tree / folder).is_dir():
                (tree / name).symlink_to(folder)
        out = Path(tmp) / "out"
        args = ["sweep", str(meta["spec"]), "--out", str(out), "--in-process"]
        args += ["--problems", str(meta["problem_label"])]
        args += ["--algorithms", str(meta["algorithm_label"]), "--seeds", str(meta["seed"])]
        if meta.get("variant"):
            args += ["--variants", str(meta["variant"])]
        env = {**os.environ, "PYTHONPATH": str(tree)}
        code = "import sys; from localpbo_core.cli import main; sys.exit(main(sys.argv[1:]))"
        subprocess.run(
            [sys.executable, "-c", code, *args],
            cwd=tree,
            env=env,
            check=True,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
        )
        return read_run(out / "runs" / f"{meta['run_id']}.json.gz")


@dataclass(frozen=True)
class Why:
    """A stored run, its making commit's re-run here and today's re-run here
    (module docstring, ``--why``)."""

    run_id: str
    algorithm: str
    commit: str
    old_digest: str
    today_digest: str
    candidates: int
    machine_identical: int
    code_identical: int
    code_gap: float
    stored_digest: str | None = None
    """The ``algorithm_digest`` of the stored run's ``code`` block when that block names
    ``commit``; it differs from ``old_digest`` when the algorithm's list of files changed
    since (``old_digest`` is taken over today's list,
    :func:`~localpbo_core.provenance.algorithm_sources`)."""

    def records(self, path: str) -> list[dict[str, Any]]:
        """The entries of ``equivalent_code.json`` (module docstring): one from ``old_digest``
        and, if it differs, one from ``stored_digest`` (both name ``commit``'s code)."""
        froms = [self.old_digest]
        if self.stored_digest is not None and self.stored_digest != self.old_digest:
            froms.append(self.stored_digest)
        return [
            {
                "run": path,
                "algorithm": self.algorithm,
                "commit": self.commit,
                "from": digest,
                "to": self.today_digest,
                "candidates": self.candidates,
                "identical": self.code_identical,
                "code_gap": self.code_gap,
                "stored_identical": self.machine_identical,
            }
            for digest in froms
        ]


def why(path: Path, commit: str | None = None) -> Why:
    """The three-way comparison of ``--why`` for the stored run at ``path``, with the code of
    ``commit`` instead of the commit that made the run if given."""
    from localpbo_core.experiments.stored_code import code_at
    from localpbo_core.provenance import ROOT, code_block
    from localpbo_core.sweep import read_run

    stored = read_run(path)
    algorithm = str(stored["settings"]["algorithm"])
    commit = commit or making_commit(stored, path)
    if commit is None:
        raise ValueError(f"{path}: no commit known for this run")
    commit = subprocess.run(
        ["git", "-C", str(ROOT), "rev-parse", "--verify", f"{commit}^{{commit}}"],
        capture_output=True,
        text=True,
        check=True,
    ).stdout.strip()
    old = rerun_at(commit, stored)
    today = rerun(stored)
    machine, _ = identical_candidates(stored, old)
    code, gap = identical_candidates(old, today)
    return Why(
        run_id=str(stored["run"]["run_id"]),
        algorithm=algorithm,
        commit=commit,
        old_digest=code_at(ROOT, commit, [algorithm])["algorithms"][algorithm],
        today_digest=str(code_block(algorithm)["algorithm_digest"]),
        candidates=len(stored["candidates"]),
        machine_identical=machine,
        code_identical=code,
        code_gap=gap,
        stored_digest=_block_digest(stored, commit),
    )


def _block_digest(doc: dict[str, Any], commit: str) -> str | None:
    """The stored run's ``algorithm_digest`` if its ``code`` block names ``commit``."""
    block = doc.get("code") or {}
    if block.get("commit") != commit or block.get("dirty"):
        return None
    digest = block.get("algorithm_digest")
    return None if digest is None else str(digest)


def _stored_code(doc: dict[str, Any]) -> tuple[str, str]:
    code = doc.get("code")
    if not isinstance(code, dict):
        return "none", "unknown"
    try:
        from localpbo_core.provenance import code_block
    except ImportError:  # an older checkout without provenance
        return str(code.get("commit")), "unknown"
    today = code_block(str(doc["settings"]["algorithm"]))["algorithm_digest"]
    changed = "no" if code.get("algorithm_digest") == today else "yes"
    return f"{str(code.get('commit'))[:10]}{'+dirty' if code.get('dirty') else ''}", changed


def compare(stored: dict[str, Any], now: dict[str, Any]) -> Drift:
    """Where ``now`` (a re-run) departs from ``stored``."""
    identical, gap = identical_candidates(stored, now)
    code, changed = _stored_code(stored)
    old_platform, new_platform = stored.get("platform"), now.get("platform")
    where = "unknown"
    if isinstance(old_platform, dict) and isinstance(new_platform, dict):
        where = "; ".join(platform_changes(old_platform, new_platform)) or "same"
    return Drift(
        run_id=str(stored["run"]["run_id"]),
        stored_code=code,
        algorithm_changed=changed,
        identical=identical,
        candidates=len(stored["candidates"]),
        first_gap=gap,
        stored_final=float(stored["records"][-1]["best_seen"]),
        now_final=float(now["records"][-1]["best_seen"]),
        platform=where,
    )


def table(drifts: Sequence[Drift]) -> list[str]:
    """One Markdown row per run."""
    lines = [
        "| run | stored code | algorithm changed since | identical candidates "
        "| first gap | final best-seen stored | now | platform stored -> now |",
        "| --- | --- | --- | ---: | ---: | ---: | ---: | --- |",
    ]
    for d in drifts:
        lines.append(
            f"| {d.run_id} | {d.stored_code} | {d.algorithm_changed} | "
            f"{d.identical} of {d.candidates} | {d.first_gap:.3g} | {d.stored_final:.6g} | "
            f"{d.now_final:.6g} | {d.platform} |"
        )
    return lines


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m localpbo_core.experiments.drift",
        description="Re-run stored runs in-process and print where they drift from the stored "
        "candidates (nothing is written).",
    )
    parser.add_argument("runs", nargs="+", help="stored run files (OUT/runs/<run_id>.json.gz)")
    parser.add_argument(
        "--why",
        action="store_true",
        help="also re-run each with the code of the commit that made it, on this machine",
    )
    parser.add_argument(
        "--record", default=None, help="with --why: add the results to this JSON list"
    )
    parser.add_argument(
        "--commit",
        default=None,
        help="with --why: compare today's code with this commit's instead of the one that "
        "made each run (e.g. the last commit before a refactoring)",
    )
    args = parser.parse_args(argv)
    from localpbo_core.sweep import read_run

    if args.why:
        return _main_why(args.runs, args.record, args.commit)
    if args.commit is not None or args.record is not None:
        parser.error("--commit and --record go with --why")
    drifts = []
    for path in args.runs:
        stored = read_run(Path(path))
        drifts.append(compare(stored, rerun(stored)))
        print(table(drifts[-1:])[-1], flush=True)
    print("\n".join(table(drifts)))
    return 0


def _main_why(paths: Sequence[str], record: str | None, commit: str | None) -> int:
    from localpbo_core.provenance import ROOT

    print(
        "| run | commit | candidates | stored = commit here | commit here = today here "
        "| first gap (code) |"
    )
    print("| --- | --- | ---: | ---: | ---: | ---: |")
    entries = []
    for p in paths:
        w = why(Path(p), commit)
        print(
            f"| {w.run_id} | {w.commit[:10]} | {w.candidates} | {w.machine_identical} "
            f"| {w.code_identical} | {w.code_gap:.3g} |",
            flush=True,
        )
        rel = Path(p).resolve()
        try:
            name = rel.relative_to(ROOT).as_posix()
        except ValueError:
            name = Path(p).as_posix()
        entries += w.records(name)
    if record is not None:
        target = Path(record)
        old = json.loads(target.read_text()) if target.is_file() else []

        def key(e: dict[str, Any]) -> tuple[str, str, str]:
            return e["run"], e["from"], e["to"]

        names = {key(e) for e in entries}
        kept = [e for e in old if key(e) not in names]
        merged = sorted(kept + entries, key=lambda e: (e["algorithm"], *key(e)))
        target.write_text(json.dumps(merged, indent=1, sort_keys=True) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
