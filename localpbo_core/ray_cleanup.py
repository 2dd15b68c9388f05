"""The embedded Ray of ``localpbo sweep`` leaves nothing behind, whatever ends the driver.

Ray started by ``ray.init()`` shuts its processes down in ``ray.shutdown()``; a driver killed
with SIGKILL never gets there, and Ray's own fate sharing then stops only part of them: its
dashboard agent and runtime-env agent (which ignore SIGTERM) outlive it, and its session
folder (logs, sockets) stays in the temporary folder. So the embedded Ray of a sweep runs

* in a **private temporary folder**, ``/tmp/lpbo-ray-<driver pid>-<random>`` (short: Ray's
  socket paths must fit in 107 bytes), which every Ray process of the session holds files of;
* under a **watchdog**: a small process in its own session (``python -m
  localpbo_core.ray_cleanup --watch PID --temp-dir DIR``) that waits for the driver to end
  (``pidfd_open``), however it ends, then stops every process holding files in that folder
  (SIGTERM, SIGKILL after :data:`WATCHDOG_GRACE_S`) and removes the folder.

A driver that stops normally or on SIGINT/SIGTERM calls :func:`clean` itself after
``ray.shutdown()``. Only when the driver and its watchdog are both SIGKILLed (e.g. a kill of
every process of a session) can a folder and processes remain; the next sweep removes them
(:func:`clean_stale`: folders whose driver is dead).
"""

from __future__ import annotations

import argparse
import contextlib
import os
import re
import select
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from collections.abc import Sequence
from pathlib import Path

PREFIX = "lpbo-ray-"
"""Name prefix of the private temporary folders (``<prefix><driver pid>-<random>``)."""
PARENT = Path("/tmp")
"""Where the private folders are made (not ``$TMPDIR``: Ray's socket paths must stay short)."""
GRACE_S = 2.0
"""Seconds between SIGTERM and SIGKILL for the processes of a Ray session whose driver is not
known to be done (:func:`clean` by default)."""
WATCHDOG_GRACE_S = 0.5
"""The same after ``ray.shutdown()`` or the driver's end: what is left then (Ray's agents,
which ignore SIGTERM, a worker still stopping) holds nothing a sweep needs."""


def make_temp_dir(parent: Path = PARENT) -> Path:
    """A new private folder for one embedded Ray session of this process."""
    return Path(tempfile.mkdtemp(prefix=f"{PREFIX}{os.getpid()}-", dir=parent))


def holders(folder: Path) -> list[int]:
    """Processes (other than this one) with an open file below ``folder`` or their working
    directory there: every process of a Ray session holds its log files in the session's
    folder (the watchdog, which names the folder only in its arguments, is not one)."""
    root = str(folder)
    found = []
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit() or int(entry.name) == os.getpid():
            continue
        links = []
        try:
            for fd in (entry / "fd").iterdir():
                with contextlib.suppress(OSError):
                    links.append(os.readlink(fd))
            with contextlib.suppress(OSError):
                links.append(os.readlink(entry / "cwd"))
        except OSError:  # gone, or not ours
            continue
        if any(link == root or link.startswith(root + "/") for link in links):
            found.append(int(entry.name))
    return sorted(found)


def stop(pids: Sequence[int], grace_s: float = GRACE_S) -> None:
    """SIGTERM each of ``pids``, SIGKILL the ones still alive after ``grace_s``."""
    for pid in pids:
        with contextlib.suppress(ProcessLookupError, PermissionError):
            os.kill(pid, signal.SIGTERM)
    deadline = time.monotonic() + grace_s
    alive = list(pids)
    while alive and time.monotonic() < deadline:
        time.sleep(0.1)
        alive = [pid for pid in alive if _running(pid)]
    for pid in alive:
        with contextlib.suppress(ProcessLookupError, PermissionError):
            os.kill(pid, signal.SIGKILL)


def _running(pid: int) -> bool:
    """``pid`` exists and is not a zombie."""
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except (OSError, IndexError):
        return False
    return state != "Z"


def clean(folder: Path, grace_s: float = GRACE_S) -> None:
    """Stop every process of the Ray session in ``folder`` and remove the folder."""
    for _ in range(3):  # a process may start another while the first ones stop
        pids = holders(folder)
        if not pids:
            break
        stop(pids, grace_s)
    shutil.rmtree(folder, ignore_errors=True)


def clean_stale(parent: Path = PARENT) -> list[Path]:
    """Clean (:func:`clean`) the private folders of drivers that no longer run; returns
    them."""
    stale = []
    for folder in sorted(parent.glob(f"{PREFIX}*")):
        match = re.fullmatch(rf"{PREFIX}(\d+)-\w+", folder.name)
        if match is None or not folder.is_dir() or _running(int(match.group(1))):
            continue
        clean(folder)
        stale.append(folder)
    return stale


def start_watchdog(folder: Path) -> subprocess.Popen[bytes]:
    """Start the watchdog of this process's Ray session in ``folder`` (module docstring)."""
    return subprocess.Popen(
        [
            sys.executable,
            "-m",
            "localpbo_core.ray_cleanup",
            "--watch",
            str(os.getpid()),
            "--temp-dir",
            str(folder),
        ],
        stdin=subprocess.DEVNULL,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        start_new_session=True,  # a signal to the driver's process group spares it
        close_fds=True,
        cwd="/",
    )


def wait_for_exit(pid: int) -> None:
    """Return once process ``pid`` has ended (at once if it does not exist)."""
    try:
        fd = os.pidfd_open(pid)
    except ProcessLookupError:
        return
    except OSError:  # no pidfd (old kernel): poll
        while _running(pid):
            time.sleep(0.5)
        return
    try:
        select.select([fd], [], [])
    finally:
        os.close(fd)


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m localpbo_core.ray_cleanup",
        description="Stop the Ray processes of a localpbo sweep's private Ray folder and remove "
        "the folder: at once, or (--watch) once the sweep's driver has ended. Without "
        "--temp-dir: the folders of sweeps whose driver no longer runs.",
    )
    parser.add_argument("--watch", type=int, default=None, help="driver pid to wait for")
    parser.add_argument("--temp-dir", default=None, help=f"the private folder ({PREFIX}*)")
    args = parser.parse_args(argv)
    if args.temp_dir is None:
        for folder in clean_stale():
            print(f"removed {folder}")
        return 0
    folder = Path(args.temp_dir)
    if not folder.name.startswith(PREFIX):
        parser.error(f"--temp-dir: {folder} is not a {PREFIX}* folder")
    if args.watch is not None:
        for sig in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP):
            signal.signal(sig, signal.SIG_IGN)  # the driver's Ctrl-C is not for the watchdog
        wait_for_exit(args.watch)
        clean(folder, WATCHDOG_GRACE_S)
        return 0
    clean(folder)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
