"""Benchmark: from a person's answer to the next duel on the judge's page, end to end.

A whole ``localpbo run --oracle human`` in this process (optimizer, simulator, judge node and
its web server, recorder) answered by a scripted person over HTTP, the way the page does it:
poll ``api/state`` until the duel is ready to judge (both episodes evaluated), "watch" for
``--think`` seconds (``--warmup-think`` during the first ``--warmup`` duels, to reach a large
model quickly), post the answer, then poll until the next duel is ready. The time from
posting the answer to seeing the next ready duel includes the optimizer's decision, the new
candidate's episode, the messages and the web request; it is timed for every answer after
``--warmup`` duels, with and without ``speculate``.

Run: ``python -m localpbo_ros.benchmarks.judge_latency [--task hopper] [--duels 400]
[--warmup 340] [--think 1.0] [--warmup-think 0]``. Prints figures; asserts nothing.
"""

from __future__ import annotations

import argparse
import json
import tempfile
import threading
import time
import urllib.request
from pathlib import Path
from typing import Any

import numpy as np

POLL_S = 0.002


def _get(url: str) -> Any:
    with urllib.request.urlopen(url, timeout=10) as r:
        return json.loads(r.read())


def _post(url: str, body: dict[str, Any]) -> Any:
    req = urllib.request.Request(url, data=json.dumps(body).encode())
    with urllib.request.urlopen(req, timeout=10) as r:
        return json.loads(r.read())


def _next_ready(url: str, after: int, deadline: float) -> dict[str, Any] | None:
    """The first ready duel with an id above ``after`` (None once the run has ended)."""
    while time.monotonic() < deadline:
        state = _get(url + "api/state")
        duel = state.get("duel")
        if duel is not None and duel["ready"] and duel["duel_id"] > after:
            return dict(duel)
        if duel is None and state.get("finished"):
            return None
        time.sleep(POLL_S)
    raise TimeoutError("no ready duel in time")


def measure(args: argparse.Namespace, speculate: bool) -> list[float]:
    """Seconds from each answer (after the warm-up) to the next ready duel."""
    from localpbo_ros.suite import run_suite

    urls: list[str] = []
    settings = {
        "run_id": f"judge-latency-{int(speculate)}",
        "algorithm": args.algorithm,
        "task": args.task,
        "budget": args.duels + 1,
        "seed": args.seed,
        "tie_threshold": 0.25,
        "speculate": speculate,
    }
    result: dict[str, Any] = {}
    with tempfile.TemporaryDirectory() as tmp:
        judge = {"state_dir": str(Path(tmp) / "judge")}

        def run() -> None:
            result["summary"] = run_suite(
                settings, Path(tmp) / "run.mcap", judge=judge, on_url=urls.append, timeout_s=3600
            )

        thread = threading.Thread(target=run, daemon=True)
        thread.start()
        while not urls:
            time.sleep(0.01)
        url = urls[0]
        deadline = time.monotonic() + 3600
        latencies: list[float] = []
        duel = _next_ready(url, -1, deadline)
        while duel is not None:
            time.sleep(args.think if duel["duel_id"] >= args.warmup else args.warmup_think)
            choice = "a" if duel["duel_id"] % 3 else "b"
            body = {
                "duel_id": duel["duel_id"],
                "first_id": duel["a"]["id"],
                "second_id": duel["b"]["id"],
                "choice": choice,
            }
            t0 = time.perf_counter()
            _post(url + "api/answer", body)
            nxt = _next_ready(url, duel["duel_id"], deadline)
            if nxt is not None and duel["duel_id"] >= args.warmup:
                latencies.append(time.perf_counter() - t0)
            duel = nxt
        thread.join(60)
    return latencies


def main(argv: list[str] | None = None) -> None:
    """Print answer-to-next-duel latency, plain and with speculation."""
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--task", default="hopper")
    parser.add_argument("--algorithm", default="turpbo")
    parser.add_argument("--duels", type=int, default=400)
    parser.add_argument("--warmup", type=int, default=340)
    parser.add_argument("--think", type=float, default=1.0)
    parser.add_argument("--warmup-think", type=float, default=0.0)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)
    print(
        f"{args.algorithm} on {args.task}, {args.duels} duels answered over HTTP; the answers "
        f"after duel {args.warmup} come {args.think} s after their duel is ready and are timed "
        "(ms)"
    )
    print(f"{'speculate':<10}{'n':>4}{'median':>9}{'p95':>9}{'max':>9}")
    for speculate in (False, True):
        x = np.asarray(measure(args, speculate)) * 1e3
        print(
            f"{str(speculate).lower():<10}{len(x):>4}{np.median(x):>9.1f}"
            f"{np.percentile(x, 95):>9.1f}{x.max():>9.1f}"
        )


if __name__ == "__main__":
    main()
