"""Stopping a process on SIGINT or SIGTERM: a guard while it starts, a request once it runs.

Every executable (the ``localpbo`` command, each node) installs :func:`guard_start` as its
very first step, before it imports anything heavy: numpy, torch and rclpy take one to two
seconds to import on a loaded machine. A signal in that window ends the process at once with
the executable's exit code and a one-line message on stderr; nothing is held yet (no bag, no
DDS participant, no controller's parameter changed), so ending at once is a clean stop.

Once the process holds something it replaces the guard by :func:`stop_on_signals`: the first
signal sets a :class:`StopRequest` that its main loop polls; the loop ends, closes what it holds
(bags finished, a controller's parameters restored) and the process exits. Later signals are
ignored, so a second Ctrl-C, or ``timeout`` and a process-group kill signalling twice, cannot cut
the clean-up short. A command that keeps Python's default behaviour (Ctrl-C raises
``KeyboardInterrupt``) calls :func:`release_start_guard` instead.

Nothing here imports more than the standard library: the module is loaded before anything else.
"""

from __future__ import annotations

import os
import signal
import sys
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from types import FrameType
from typing import Any, NoReturn

STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM)


def shell_code(signum: int) -> int:
    """The shell's code for a process ended by signal ``signum``: 128 + signum (130 for
    SIGINT, 143 for SIGTERM)."""
    return 128 + signum


class StopRequest(threading.Event):
    """Set by the first SIGINT or SIGTERM; ``signum`` says which (0 until then).

    First as Python handles them: signals that arrive while the main thread is inside one long
    C call are handled after it in signal-number order, so SIGINT counts as first then.
    """

    def __init__(self) -> None:
        super().__init__()
        self.signum = 0

    def request(self, signum: int) -> None:
        """Record the first stop signal; later ones change nothing."""
        if not self.is_set():
            self.signum = signum
            self.set()

    @property
    def signal_name(self) -> str:
        """``SIGINT``, ``SIGTERM`` or empty when no stop was requested."""
        return signal.Signals(self.signum).name if self.signum else ""


def stop_on_signals() -> StopRequest:
    """Install handlers for SIGINT and SIGTERM (for the rest of the process, replacing the start
    guard); the returned request is set by the first signal, later ones are ignored."""
    global _previous
    requested = StopRequest()

    def handler(signum: int, frame: FrameType | None) -> None:
        requested.request(signum)

    for sig in STOP_SIGNALS:
        signal.signal(sig, handler)
    _previous = None  # the guard is gone
    return requested


@contextmanager
def stop_requests() -> Iterator[StopRequest]:
    """:func:`stop_on_signals` for a block: the handlers from before come back when the block
    ends without a stop request; after one they stay (later signals ignored) while the caller
    finishes and exits."""
    previous = {sig: signal.getsignal(sig) for sig in STOP_SIGNALS}
    request = stop_on_signals()
    try:
        yield request
    finally:
        if not request.is_set():
            for sig, handler in previous.items():
                signal.signal(sig, handler)


_previous: dict[signal.Signals, Any] | None = None
"""The handlers the start guard replaced (None: no guard installed)."""


def guard_start(program: str, code_of: Callable[[int], int]) -> None:
    """End the process at once on SIGINT or SIGTERM until it installs its own handling.

    ``program`` names the executable in the message (``<program>: stopped by SIGINT while
    starting``); ``code_of(signum)`` is its exit code (the nodes: 0; ``localpbo``:
    :func:`shell_code`). The message is written with ``os.write``: a signal handler must not
    use a Python stream the interrupted code may be writing to.
    """
    global _previous

    def handler(signum: int, frame: FrameType | None) -> None:
        name = signal.Signals(signum).name
        os.write(2, f"{program}: stopped by {name} while starting\n".encode())
        _wait_for_children(CHILD_WAIT_S)
        exit_now(code_of(signum))

    previous = {sig: signal.getsignal(sig) for sig in STOP_SIGNALS}
    for sig in STOP_SIGNALS:
        signal.signal(sig, handler)
    _previous = previous


CHILD_WAIT_S = 2.0
"""Seconds a process stopped while starting waits for the helper processes its imports started
(e.g. glfw's library check, a Python child reading from a pipe to this process): ended at
once, this process would leave them writing into a closed pipe, with a traceback of theirs."""


def _wait_for_children(timeout_s: float) -> None:
    """Reap this process's children as they end, for at most ``timeout_s`` seconds; then kill
    those left (e.g. one waiting for input this process will never write)."""
    end = time.monotonic() + timeout_s
    while time.monotonic() < end:
        try:
            pid, _ = os.waitpid(-1, os.WNOHANG)
        except ChildProcessError:  # none left
            return
        if pid == 0:  # some still running
            time.sleep(0.01)
    for pid in _children():
        try:
            os.kill(pid, signal.SIGKILL)
        except OSError:
            pass


def _children() -> list[int]:
    """This process's children (Linux: ``/proc/self/task/*/children``; elsewhere none)."""
    pids: list[int] = []
    try:
        for task in os.listdir("/proc/self/task"):
            with open(f"/proc/self/task/{task}/children") as fh:
                pids += [int(p) for p in fh.read().split()]
    except OSError:
        pass
    return pids


def release_start_guard() -> None:
    """Give SIGINT and SIGTERM back the handlers they had before :func:`guard_start` (Python's
    defaults, or ``SIG_IGN`` when the process was started with them ignored); no-op without a
    guard."""
    global _previous
    if _previous is None:
        return
    for sig, handler in _previous.items():
        signal.signal(sig, handler)
    _previous = None


def exit_now(code: int) -> NoReturn:
    """Flush Python's and C's output buffers and end the process with ``code`` at once, without
    the interpreter's finalization: whatever the process held is closed by then, and skipping
    finalization skips the DDS library's static destructors, which are known to hang now and
    then at exit."""
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError, RuntimeError):  # closed, or being written when signalled
            pass
    _flush_c_stdio()
    os._exit(code)


def _flush_c_stdio() -> None:
    """Flush C's stdio buffers (rcutils may log to a buffered C stdout).

    A signal can arrive in the middle of an import of ``ctypes`` or of a module it needs
    (``struct``): then ``ctypes`` cannot be imported, and nothing was written through C's
    stdio yet (rcutils logs only once a node runs), so there is nothing to flush.
    """
    try:
        import ctypes

        ctypes.CDLL(None).fflush(None)
    except (ImportError, AttributeError):
        pass
