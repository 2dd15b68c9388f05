"""Benchmark: what a ``localpbo sweep`` leaves behind after SIGINT, SIGTERM and SIGKILL.

Per signal: start a real sweep (TuRPBO on Hartmann 6, six seeds, ``--workers 2``, into a
temporary folder), send the signal once a run is stored, and print the driver's exit code and
how long it took to exit, then poll the embedded Ray's private folder
(:mod:`localpbo_core.ray_cleanup`) until no process holds files in it and it is gone, and
print when that was (or what is left after ``--wait`` seconds). Prints figures; asserts
nothing (``tests/test_sweep.py`` does).
"""

from __future__ import annotations

import argparse
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from localpbo_core import ray_cleanup


def measure(signum: signal.Signals, wait_s: float) -> str:
    out = Path(tempfile.mkdtemp(prefix="sweep-signals-"))
    cmd = [sys.executable, "-m", "localpbo_core.cli", "sweep", "synthetic", "--out", str(out)]
    cmd += ["--problems", "hartmann6", "--algorithms", "turpbo", "--seeds", "0-5"]
    cmd += ["--workers", "2", "--no-progress"]
    proc = subprocess.Popen(
        cmd,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
    )
    try:
        runs = out / "runs"
        while not (runs.is_dir() and any(runs.glob("*.json.gz"))):
            if proc.poll() is not None:
                return f"{signum.name}: the sweep ended before a run was stored"
            time.sleep(0.2)
        folder = next(ray_cleanup.PARENT.glob(f"{ray_cleanup.PREFIX}{proc.pid}-*"))
        held = len(ray_cleanup.holders(folder))
        proc.send_signal(signum)
        sent = time.monotonic()
        _, err = proc.communicate(timeout=120)
        exited = time.monotonic() - sent
        while ray_cleanup.holders(folder) or folder.exists():
            if time.monotonic() - sent > wait_s:
                left = ray_cleanup.holders(folder)
                return (
                    f"{signum.name:7}: exit {proc.returncode} after {exited:.1f} s; after "
                    f"{wait_s:g} s still {len(left)} processes, folder "
                    f"{'kept' if folder.exists() else 'removed'}"
                )
            time.sleep(0.1)
        return (
            f"{signum.name:7}: {held} processes held the folder; exit {proc.returncode} after "
            f"{exited:.1f} s{' (traceback)' if 'Traceback' in err else ''}; nothing left "
            f"{time.monotonic() - sent:.1f} s after the signal"
        )
    finally:
        if proc.poll() is None:
            proc.kill()
        shutil.rmtree(out, ignore_errors=True)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m localpbo_core.benchmarks.sweep_signals",
        description="What a localpbo sweep leaves behind after SIGINT, SIGTERM and SIGKILL "
        "(prints figures).",
    )
    parser.add_argument(
        "--signals", default="SIGINT,SIGTERM,SIGKILL", help="comma-separated signal names"
    )
    parser.add_argument("--wait", type=float, default=60.0, help="seconds to wait for cleanup")
    args = parser.parse_args(argv)
    for name in args.signals.split(","):
        print(measure(signal.Signals[name.strip()], args.wait), flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
