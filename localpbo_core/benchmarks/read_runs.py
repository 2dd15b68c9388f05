"""Reading stored runs: :func:`localpbo_core.sweep.read_run` against the standard library's
``json`` on the same files, in the same process.

The results page reads every stored run (thousands of gzip-JSON documents, a few hundred MB
of JSON); parsing dominates. For every ``--every``-th run file under the given folders
(default: ``docs/results`` and ``docs/pending``), both readers parse the same bytes after one
shared decompression; printed: files, MB of JSON, seconds of each, the ratio json / ours and
whether every document came out equal (floats compared bit for bit by their ``repr``):

    python -m localpbo_core.benchmarks.read_runs [--every 10] [FOLDER ...]
"""

from __future__ import annotations

import argparse
import gzip
import json
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from localpbo_core.provenance import ROOT


def _same(a: Any, b: Any) -> bool:
    """Equal documents, floats equal in their bits (``repr`` round-trips a float exactly)."""
    if isinstance(a, float) or isinstance(b, float):
        return type(a) is type(b) and repr(a) == repr(b)
    if isinstance(a, dict):
        return isinstance(b, dict) and a.keys() == b.keys() and all(_same(a[k], b[k]) for k in a)
    if isinstance(a, list):
        return isinstance(b, list) and len(a) == len(b) and all(map(_same, a, b))
    return type(a) is type(b) and a == b


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m localpbo_core.benchmarks.read_runs",
        description="Time read_run's parser against json on the stored runs.",
    )
    parser.add_argument("folders", nargs="*", help="default: docs/results and docs/pending")
    parser.add_argument("--every", type=int, default=10, help="every N-th run file (default 10)")
    args = parser.parse_args(argv)
    if args.every < 1:
        parser.error("--every: must be at least 1")
    import orjson

    folders = [Path(f) for f in args.folders] or [ROOT / "docs/results", ROOT / "docs/pending"]
    files = sorted(p for f in folders for p in f.glob("*/runs/*.json.gz"))[:: args.every]
    if not files:
        parser.error("no run files (*/runs/*.json.gz) under the folders")
    raw = [gzip.decompress(p.read_bytes()) for p in files]
    start = time.perf_counter()
    reference = [json.loads(r) for r in raw]
    json_s = time.perf_counter() - start
    start = time.perf_counter()
    ours = [orjson.loads(r) for r in raw]
    ours_s = time.perf_counter() - start
    equal = all(map(_same, reference, ours))
    mb = sum(map(len, raw)) / 1e6
    print(f"{'files':>6} {'MB':>8} {'json s':>8} {'orjson s':>9} {'json/ours':>10} equal")
    print(f"{len(files):6d} {mb:8.1f} {json_s:8.2f} {ours_s:9.2f} {json_s / ours_s:10.2f} {equal}")
    return 0 if equal else 1


if __name__ == "__main__":
    raise SystemExit(main())
