"""Screenshot of the judge's page during a Hopper duel (README's ``docs/judge.png``).

``python -m localpbo_ros.benchmarks.judge_screenshot [--out docs/judge.png]`` runs README's
command for a person, ``localpbo run --task hopper --oracle human --budget 16 --run-id
mine`` (plus
``--out`` a temporary folder and ``--no-progress``), as a separate process, exactly as a user
would; opens the printed URL in headless chromium (Debian's ``chromium`` and
``chromium-driver``); lets the first duel's two episodes play for ``--at`` seconds of screen
time, pauses them, saves the screenshot, and answers the remaining duels ("A better") so the
run ends. Prints what the first duel showed (episode lengths, playback rate).
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

README_COMMAND = [
    "run",
    "--task",
    "hopper",
    "--oracle",
    "human",
    "--budget",
    "16",
    "--run-id",
    "mine",
]
"""README's command for a person judging (after ``localpbo``)."""


def until(pred: Callable[[], Any], timeout: float) -> Any:
    """The first true value of ``pred()``, polled every 50 ms for ``timeout`` seconds
    (TimeoutError after that)."""
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
    parser.add_argument("--at", type=float, default=1.6, help="seconds of replay shown")
    parser.add_argument("--chromium", default="/usr/bin/chromium")
    parser.add_argument("--chromedriver", default="/usr/bin/chromedriver")
    args = parser.parse_args(argv)

    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    with tempfile.TemporaryDirectory() as tmp:
        command = [sys.executable, "-m", "localpbo_ros.commands", *README_COMMAND]
        command += ["--out", tmp, "--no-progress"]
        print("running: localpbo " + " ".join(README_COMMAND), flush=True)
        proc = subprocess.Popen(
            command, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=os.environ
        )
        assert proc.stdout is not None
        lines: list[str] = []

        def read() -> None:
            assert proc.stdout is not None
            for line in proc.stdout:
                lines.append(line)

        reader = threading.Thread(target=read, daemon=True)
        reader.start()
        printed = until(lambda: next((ln for ln in lines if "judge the duels at " in ln), ""), 120)
        url = printed.split("judge the duels at ", 1)[1].split()[0]
        options = webdriver.ChromeOptions()
        options.binary_location = args.chromium
        for arg in ("--headless=new", "--no-sandbox", "--disable-gpu", "--hide-scrollbars"):
            options.add_argument(arg)
        options.add_argument("--window-size=1180,1240")
        driver = webdriver.Chrome(service=Service(args.chromedriver), options=options)
        try:
            driver.get(url)
            until(lambda: driver.find_element("id", "answer-a").is_enabled(), 120)
            until(lambda: driver.execute_script("return !!(replay.a && replay.b)"), 60)
            driver.find_element("id", "replay").click()
            time.sleep(args.at)
            driver.find_element("id", "play").click()  # pause on this frame
            time.sleep(0.3)
            shown = driver.execute_script(
                "return [episodeSeconds(replay.a), episodeSeconds(replay.b), effectiveRate(),"
                " state.duel.duel_id]"
            )
            Path(args.out).parent.mkdir(parents=True, exist_ok=True)
            driver.save_screenshot(args.out)
            print(
                f"wrote {args.out}: duel {shown[3]}, episodes {shown[0]:.2f} s and "
                f"{shown[1]:.2f} s, playing at {shown[2]:.2f}x"
            )
            while proc.poll() is None:
                ready = driver.execute_script(
                    "return !$('answer-a').disabled && settled() && !inFlight"
                )
                if ready:
                    driver.find_element("id", "answer-a").click()
                time.sleep(0.3)
        finally:
            driver.quit()
            if proc.poll() is None:
                proc.terminate()
            proc.wait(60)
        reader.join(5)
        print("".join(lines[-8:]), end="")
    return 0 if proc.returncode == 0 else 1


if __name__ == "__main__":
    raise SystemExit(main())
