"""Benchmark: from a person's key press to the next duel's buttons, in a real browser.

A whole ``localpbo run --task hopper --oracle human`` (the settings that command builds, in
this process) is judged in headless Chromium (selenium + Debian's chromium/chromedriver) by a
scripted person: wait until the answer buttons are enabled (the duel is ready), wait the
answer delay, press the key of the answer (``a``, ``b`` or ``t`` for "can't tell"), and time
from the key event to the moment the buttons are enabled again for the next duel. Both
moments are taken in the page (``performance.now()`` in a capture-phase ``keydown`` listener
and in a ``MutationObserver`` on the A button's ``disabled`` attribute), so the figure is
what the person waits for: the answer's HTTP post, the journal, the outcome message, the
optimizer's decision (or the adopted branch), the new candidate's episode (or the one run
ahead), the push of the new state to the page and its rendering.

Each of ``--delays`` (seconds after the buttons were enabled) is run for ``--per-kind``
answers of each kind, interleaved (A, B, can't tell, A, ...), after ``--warmup`` answers at
the first delay that are not timed (the initial design's duels are asked together: no
decision to wait for); all of it with speculation off, then on.

Run from a plain shell (no thread variables): ``python -m
localpbo_ros.benchmarks.judge_keys [--delays 0.3,0.5,1,3] [--per-kind 6] [--warmup 8]``.
Prints p50/p95 per delay and answer kind, and the machine's load; asserts nothing.
"""

from __future__ import annotations

import argparse
import os
import platform
import shutil
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np

KEYS = {"a": "a", "b": "b", "tie": "t"}
"""The page's key for each answer kind."""

PROBE = """
window.__kb = {t: null, prev: null, lat: null, readyAt: null};
const kb = window.__kb;
const button = document.getElementById("answer-a");
window.addEventListener("keydown", (e) => {
  if (["a", "b", "t"].includes(e.key) && state && state.duel && state.duel.ready) {
    kb.t = performance.now();
    kb.prev = state && state.duel ? state.duel.duel_id : null;
    kb.lat = null;
  }
}, true);
new MutationObserver(() => {
  if (button.disabled || !state || !state.duel) return;
  kb.readyAt = performance.now();
  if (kb.t !== null && kb.lat === null && state.duel.duel_id !== kb.prev) {
    kb.lat = kb.readyAt - kb.t;
  }
}).observe(button, {attributes: true, attributeFilter: ["disabled"]});
"""

READY = "return !document.getElementById('answer-a').disabled && !!state && !!state.duel;"


def _browser() -> Any:
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    options = webdriver.ChromeOptions()
    options.binary_location = shutil.which("chromium") or "/usr/bin/chromium"
    for arg in ("--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage"):
        options.add_argument(arg)
    options.add_argument("--window-size=1280,1100")
    service = Service(shutil.which("chromedriver") or "/usr/bin/chromedriver")
    return webdriver.Chrome(service=service, options=options)


def _settings(budget: int, seed: int, speculate: bool) -> dict[str, Any]:
    """The optimizer parameters ``localpbo run --task hopper --oracle human`` builds."""
    from localpbo_ros.commands import add_subcommands, run_settings

    parser = argparse.ArgumentParser()
    add_subcommands(parser.add_subparsers())
    words = ["run", "--task", "hopper", "--oracle", "human", "--budget", str(budget)]
    words += ["--seed", str(seed), "--run-id", f"keys-{int(speculate)}"]
    words.append("--speculate" if speculate else "--no-speculate")
    args = parser.parse_args(words)
    return run_settings(args)


def _wait(browser: Any, script: str, timeout_s: float, poll_s: float = 0.002) -> Any:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        got = browser.execute_script(script)
        if got:
            return got
        time.sleep(poll_s)
    return None


def measure(
    args: argparse.Namespace, speculate: bool
) -> tuple[dict[tuple[float, str], list[float]], dict[str, int]]:
    """Latencies (ms) by (delay, kind) of one run, and the optimizer's and simulator's
    counters (speculated answers, episodes run ahead)."""
    from selenium.webdriver.common.action_chains import ActionChains

    from localpbo_ros.suite import run_suite

    delays = [float(d) for d in args.delays.split(",")]
    plan = [(delays[0], ("a", "b", "tie")[i % 3], False) for i in range(args.warmup)]
    for delay in delays:
        plan += [(delay, ("a", "b", "tie")[i % 3], True) for i in range(3 * args.per_kind)]
    urls: list[str] = []
    out: dict[tuple[float, str], list[float]] = {}
    stop = threading.Event()
    with tempfile.TemporaryDirectory() as tmp:
        settings = _settings(len(plan) + 12, args.seed, speculate)
        judge = {"state_dir": str(Path(tmp) / "judge")}
        bag = Path(tmp) / "run.mcap"

        def run() -> None:
            run_suite(settings, bag, judge=judge, on_url=urls.append, timeout_s=3600, stop=stop)

        thread = threading.Thread(target=run, daemon=True)
        thread.start()
        while not urls:
            time.sleep(0.01)
        browser = _browser()
        try:
            browser.get(urls[0])
            browser.execute_script(PROBE)
            for delay, kind, timed in plan:
                if not _wait(browser, READY, 600):
                    break
                since = browser.execute_script(
                    "return window.__kb.readyAt === null ? 0 : "
                    "(performance.now() - window.__kb.readyAt) / 1000;"
                )
                time.sleep(max(0.0, delay - float(since)))
                ActionChains(browser).send_keys(KEYS[kind]).perform()
                lat = _wait(browser, "return window.__kb.lat;", 600)
                if lat is None:
                    break
                if timed:
                    out.setdefault((delay, kind), []).append(float(lat))
        finally:
            browser.quit()
            stop.set()
            thread.join(60)
        return out, _counters(bag)


def _counters(bag: Path) -> dict[str, int]:
    """The optimizer's and the simulator's last recorded counters (speculated answers,
    episodes run ahead and used)."""
    from localpbo_msgs_py import Status
    from localpbo_msgs_py.bag import read_messages
    from localpbo_msgs_py.topics import STATUS

    last: dict[str, dict[str, int]] = {}
    for rec in read_messages(bag):
        if rec.topic == STATUS.name:
            status = Status.decode(rec.message)
            if isinstance(status, Status):
                last[status.node] = dict(status.counters)
    opt, sim = last.get("optimizer_node", {}), last.get("sim_node", {})
    return {
        "duels": opt.get("duels_done", 0),
        "speculated": opt.get("speculated", 0),
        "episodes_ahead": sim.get("episodes_ahead", 0),
        "episodes_ahead_used": sim.get("episodes_ahead_used", 0),
    }


def main(argv: list[str] | None = None) -> None:
    """Print key-to-buttons-enabled p50/p95 per answer delay and kind, speculation off/on."""
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--delays", default="0.3,0.5,1,3")
    parser.add_argument("--per-kind", type=int, default=6)
    parser.add_argument("--warmup", type=int, default=8)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)
    threads = {k: os.environ[k] for k in ("OMP_NUM_THREADS", "MKL_NUM_THREADS") if k in os.environ}
    print(
        f"localpbo run --task hopper --oracle human, judged in headless Chromium; "
        f"{platform.node()}, {os.cpu_count()} cores, load {os.getloadavg()[0]:.1f} at start, "
        f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}"
        + (f", thread variables {threads}" if threads else "")
    )
    print("key press to the next duel's buttons enabled (ms)")
    print(f"{'speculate':<10}{'delay s':>8}{'kind':>6}{'n':>4}{'p50':>8}{'p95':>8}{'max':>8}")
    for speculate in (False, True):
        lat, counts = measure(args, speculate)
        for (delay, kind), xs in sorted(lat.items()):
            x = np.asarray(xs)
            print(
                f"{str(speculate).lower():<10}{delay:>8.1f}{kind:>6}{len(x):>4}"
                f"{np.median(x):>8.0f}{np.percentile(x, 95):>8.0f}{x.max():>8.0f}"
            )
        every = np.concatenate([np.asarray(v) for v in lat.values()]) if lat else np.zeros(1)
        print(
            f"{str(speculate).lower():<10}{'all':>8}{'all':>6}{len(every):>4}"
            f"{np.median(every):>8.0f}{np.percentile(every, 95):>8.0f}{every.max():>8.0f}"
            f"   (load {os.getloadavg()[0]:.1f}; {counts})"
        )


if __name__ == "__main__":
    main()
