"""Screenshot of the judge's page during a Hopper duel (README's ``docs/judge.png``).

``python -m localpbo_ros.benchmarks.judge_screenshot [--out docs/judge.png]`` runs
``localpbo run --task hopper --oracle human`` in this process (Sobol, budget 3, seed 1; the
published ARS policy, clipped into the task's box, as the warm start, so one of the first two
candidates hops; answers journaled in a temporary folder), opens the page in headless
chromium (Debian's ``chromium`` and ``chromium-driver``), lets the two episodes play for
``--at`` seconds, pauses them, saves the screenshot and answers the remaining duels so the run ends.
"""

from __future__ import annotations

import argparse
import json
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

from localpbo_sims import load_ars_policy, make_task

from localpbo_ros.suite import run_suite


def _wait(pred: Any, timeout: float) -> Any:
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        value = pred()
        if value:
            return value
        time.sleep(0.05)
    raise TimeoutError("the page did not get there in time")


def main(argv: list[str] | None = None) -> int:
    """Take the screenshot; returns the exit code."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="docs/judge.png")
    parser.add_argument("--at", type=float, default=1.2, help="seconds of replay shown")
    parser.add_argument("--chromium", default="/usr/bin/chromium")
    parser.add_argument("--chromedriver", default="/usr/bin/chromedriver")
    args = parser.parse_args(argv)

    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    with tempfile.TemporaryDirectory() as tmp:
        urls: list[str] = []
        task = make_task("hopper")
        warm = task.theta_from_weights(load_ars_policy("hopper").weights).theta
        settings = {"run_id": "hopper-demo", "algorithm": "sobol", "task": "hopper"}
        settings.update({"budget": 3, "seed": 1})
        settings["algorithm_options"] = json.dumps({"warm_start": [float(v) for v in warm]})
        thread = threading.Thread(
            target=run_suite,
            args=(settings, Path(tmp) / "hopper-demo.mcap"),
            kwargs={"judge": {"state_dir": tmp}, "on_url": urls.append, "timeout_s": 120},
            daemon=True,
        )
        thread.start()
        _wait(lambda: urls, 60)
        options = webdriver.ChromeOptions()
        options.binary_location = args.chromium
        for arg in ("--headless=new", "--no-sandbox", "--disable-gpu", "--hide-scrollbars"):
            options.add_argument(arg)
        options.add_argument("--window-size=1180,1240")
        driver = webdriver.Chrome(service=Service(args.chromedriver), options=options)
        try:
            driver.get(urls[0])
            _wait(lambda: driver.find_element("id", "answer-a").is_enabled(), 60)
            _wait(lambda: driver.find_element("id", "canvas-b").is_displayed(), 30)
            driver.find_element("id", "replay").click()
            time.sleep(args.at)
            driver.find_element("id", "play").click()  # pause on this frame
            time.sleep(0.3)
            driver.save_screenshot(args.out)
            print(f"wrote {args.out}")
            while thread.is_alive():
                if driver.find_element("id", "answer-a").is_enabled():
                    driver.find_element("id", "answer-a").click()
                time.sleep(0.5)
        finally:
            driver.quit()
        thread.join(30)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
