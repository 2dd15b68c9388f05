"""Re-run stored runs with the code at hand and show where they drift from what was stored.

``python -m localpbo_core.experiments.drift RUN_FILE...`` rebuilds each stored run's plan from
its spec (``run.spec``, ``run.run_id``), runs it in-process (as ``localpbo sweep
--in-process`` does) and prints per run: the code version stored with it (``code`` block,
:mod:`localpbo_core.provenance`; "none" for runs stored before runs carried one), whether its
algorithm's sources changed since, how many leading candidates are bit-identical, the largest
coordinate difference at the first candidate that differs, and the final best-seen stored
and now. Nothing is written.

To tell drift by code from drift by machine, run the same command with an older checkout
first on ``PYTHONPATH`` (``git archive <commit> | tar -x -C DIR``, then ``PYTHONPATH=DIR
python localpbo_core/experiments/drift.py ...``): the run's own commit reproduces its stored
candidates up to the machine's rounding, today's code may not.
"""

from __future__ import annotations

import argparse
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np


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


def rerun(doc: dict[str, Any]) -> dict[str, Any]:
    """The document ``localpbo sweep`` would store for ``doc``'s plan today."""
    from localpbo_core.experiments import load_spec
    from localpbo_core.sweep import execute_run

    meta = doc["run"]
    plan = next(p for p in load_spec(meta["spec"]).runs() if p.run_id == meta["run_id"])
    return execute_run(plan)


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
    a = [np.asarray(c["native"], dtype=np.float64) for c in stored["candidates"]]
    b = [np.asarray(c["native"], dtype=np.float64) for c in now["candidates"]]
    identical = 0
    gap = 0.0
    for x, y in zip(a, b, strict=False):
        if x.shape == y.shape and np.array_equal(x, y):
            identical += 1
            continue
        gap = float(np.max(np.abs(x - y))) if x.shape == y.shape else float("inf")
        break
    code, changed = _stored_code(stored)
    return Drift(
        run_id=str(stored["run"]["run_id"]),
        stored_code=code,
        algorithm_changed=changed,
        identical=identical,
        candidates=len(a),
        first_gap=gap,
        stored_final=float(stored["records"][-1]["best_seen"]),
        now_final=float(now["records"][-1]["best_seen"]),
    )


def table(drifts: Sequence[Drift]) -> list[str]:
    """One Markdown row per run."""
    lines = [
        "| run | stored code | algorithm changed since | identical candidates "
        "| first gap | final best-seen stored | now |",
        "| --- | --- | --- | ---: | ---: | ---: | ---: |",
    ]
    for d in drifts:
        lines.append(
            f"| {d.run_id} | {d.stored_code} | {d.algorithm_changed} | "
            f"{d.identical} of {d.candidates} | {d.first_gap:.3g} | {d.stored_final:.6g} | "
            f"{d.now_final:.6g} |"
        )
    return lines


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m localpbo_core.experiments.drift",
        description="Re-run stored runs in-process and print where they drift from the stored "
        "candidates (nothing is written).",
    )
    parser.add_argument("runs", nargs="+", help="stored run files (OUT/runs/<run_id>.json.gz)")
    args = parser.parse_args(argv)
    from localpbo_core.sweep import read_run

    drifts = []
    for path in args.runs:
        stored = read_run(Path(path))
        drifts.append(compare(stored, rerun(stored)))
        print(table(drifts[-1:])[-1], flush=True)
    print("\n".join(table(drifts)))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
