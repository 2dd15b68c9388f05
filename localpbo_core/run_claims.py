"""Claims on the runs of one sweep folder, so that two sweeps never compute the same run.

A sweep claims a run before computing it and gives the claim up once the run is stored or
has failed. A claim is an exclusive ``flock`` on ``OUT/.claims/<run_id>.claim``; the file
says who holds it (process id, host, start time). The kernel drops the lock when its
process ends, however it ends (SIGKILL too), so a claim never outlives its sweep and needs
no timeout: the next sweep takes the run over.

Two sweeps started on the same folder therefore share its runs instead of computing them
twice: an in-process sweep claims each run just before it computes it and passes over the
runs another sweep holds, so the same command started in two shells runs on two cores. A
sweep on Ray claims the runs it submits.

The lock is as good as the file system's: ``flock`` holds on local file systems, and on
Linux also on NFS (v4, where the client emulates it by a byte-range lock over the whole
file) when the folder is shared between hosts.
"""

from __future__ import annotations

import contextlib
import fcntl
import json
import os
import socket
import time
from dataclasses import dataclass
from pathlib import Path

CLAIMS_DIR = ".claims"
"""The folder of the claim files, inside a sweep's ``OUT``."""

CLAIM_SUFFIX = ".claim"

PROBE_RETRIES = 3
PROBE_WAIT_S = 0.02
"""A failed claim is tried again this many times this far apart: :func:`holder` takes a
shared lock for an instant to see whether a claim is held, and that instant must not make a
sweep pass over a run nobody computes."""


def claim_path(out: Path, run_id: str) -> Path:
    """``OUT/.claims/<run_id>.claim``."""
    return out / CLAIMS_DIR / f"{run_id}{CLAIM_SUFFIX}"


@dataclass(frozen=True)
class Holder:
    """Who holds a claim, as its file says (None: not written yet or unreadable)."""

    pid: int | None = None
    host: str | None = None
    since: str | None = None

    def describe(self) -> str:
        """E.g. ``"pid 4242 on host lab-3 since 2026-11-29T12:00:00Z"``."""
        if self.pid is None:
            return "another sweep"
        text = f"pid {self.pid}"
        if self.host:
            text += f" on host {self.host}"
        if self.since:
            text += f" since {self.since}"
        return text


class Claim:
    """A held claim; :meth:`release` (or leaving its ``with`` block) gives it up and removes
    its file."""

    def __init__(self, path: Path, fd: int) -> None:
        self.path = path
        self._fd: int | None = fd

    @property
    def held(self) -> bool:
        """True until released."""
        return self._fd is not None

    def release(self) -> None:
        """Remove the file, then drop the lock (in this order: a sweep that opened the file
        before it was removed sees it is gone once it gets the lock, and tries again on a
        new file). Releasing twice is harmless."""
        fd, self._fd = self._fd, None
        if fd is None:
            return
        try:
            with contextlib.suppress(FileNotFoundError):
                self.path.unlink()
        finally:
            os.close(fd)  # drops the lock

    def __enter__(self) -> Claim:
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.release()


def try_claim(out: Path, run_id: str) -> Claim | None:
    """Claim run ``run_id`` of the sweep folder ``out``; None if another process holds it.

    Raises:
        OSError: the claims folder cannot be made or written.
    """
    path = claim_path(out, run_id)
    path.parent.mkdir(parents=True, exist_ok=True)
    for attempt in range(PROBE_RETRIES + 1):
        fd = _locked(path)
        if fd is not None:
            info = {"pid": os.getpid(), "host": socket.gethostname(), "since": _now()}
            os.ftruncate(fd, 0)
            os.pwrite(fd, (json.dumps(info) + "\n").encode(), 0)
            return Claim(path, fd)
        if attempt < PROBE_RETRIES:
            time.sleep(PROBE_WAIT_S)
    return None


def holder(out: Path, run_id: str) -> Holder | None:
    """Who holds run ``run_id``'s claim; None if nobody does (a claim file left by a process
    that ended holds nothing)."""
    path = claim_path(out, run_id)
    try:
        fd = os.open(path, os.O_RDONLY)
    except FileNotFoundError:
        return None
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)
        except BlockingIOError:
            return _read_holder(fd)
        fcntl.flock(fd, fcntl.LOCK_UN)
        return None
    finally:
        os.close(fd)


def _locked(path: Path) -> int | None:
    """An open descriptor of ``path`` with its exclusive lock, or None if another holds it."""
    while True:
        fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            os.close(fd)
            return None
        try:
            now = os.stat(path)
        except FileNotFoundError:
            now = None
        mine = os.fstat(fd)
        if now is not None and (now.st_dev, now.st_ino) == (mine.st_dev, mine.st_ino):
            return fd
        os.close(fd)  # the holder removed the file after it was opened here: a new one


def _read_holder(fd: int) -> Holder:
    try:
        info = json.loads(os.pread(fd, 4096, 0) or b"null")
    except (OSError, ValueError):
        return Holder()
    if not isinstance(info, dict):
        return Holder()
    pid, host, since = info.get("pid"), info.get("host"), info.get("since")
    return Holder(
        pid if isinstance(pid, int) and not isinstance(pid, bool) else None,
        host if isinstance(host, str) else None,
        since if isinstance(since, str) else None,
    )


def _now() -> str:
    return time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())
