"""The stop guard and stop requests (``localpbo_core.stopping``), in child processes."""

from __future__ import annotations

import signal
import subprocess
import sys

import pytest

GUARDED = """
import os, signal, subprocess, sys, time
from localpbo_core.stopping import guard_start, shell_code
guard_start("probe", shell_code)
{body}
os.kill(os.getpid(), signal.{sig})
time.sleep(30)
print("not stopped")
"""

HELPER = (
    "subprocess.Popen([sys.executable, '-c', 'import sys; sys.stdin.read(); print(\"x\" * 9)'],"
    " stdin=subprocess.PIPE, stdout=subprocess.PIPE)"
)
"""A helper child as an import may start one (glfw's library check): it reads its input, then
writes its answer into a pipe to this process."""


def _default_sigint() -> None:
    # as from a terminal: a shell starts background jobs (e.g. `make test &`) with SIGINT
    # ignored, and Python then keeps it ignored
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def run(script: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-c", script],
        capture_output=True,
        text=True,
        timeout=60,
        preexec_fn=_default_sigint,
    )


@pytest.mark.parametrize("sig", ["SIGINT", "SIGTERM"])
def test_guard_ends_the_process_at_once(sig: str) -> None:
    done = run(GUARDED.format(body="", sig=sig))
    assert done.returncode == 128 + signal.Signals[sig]
    assert done.stderr == f"probe: stopped by {sig} while starting\n"
    assert "not stopped" not in done.stdout


def test_guard_leaves_no_helper_writing_into_a_closed_pipe() -> None:
    # the helper waits for input the process will never send: it is ended, not left to
    # write its answer into a closed pipe (a BrokenPipeError traceback of its own)
    done = run(GUARDED.format(body=f"child = {HELPER}", sig="SIGTERM"))
    assert done.returncode == 143, done.stderr
    assert "Traceback" not in done.stderr, done.stderr


def test_released_guard_gives_python_its_defaults() -> None:
    body = "from localpbo_core.stopping import release_start_guard; release_start_guard()"
    done = run(GUARDED.format(body=body, sig="SIGINT"))
    assert done.returncode == -signal.SIGINT and "KeyboardInterrupt" in done.stderr


def test_stop_requests_restore_on_a_normal_end_and_keep_after_a_stop() -> None:
    script = """
import os, signal
from localpbo_core.stopping import stop_requests
with stop_requests() as quiet:
    pass
print(signal.getsignal(signal.SIGINT) is signal.default_int_handler, quiet.signal_name == "")
with stop_requests() as stop:
    os.kill(os.getpid(), signal.SIGTERM)
    os.kill(os.getpid(), signal.SIGINT)  # later signals are ignored
    print(stop.is_set(), stop.signal_name)
os.kill(os.getpid(), signal.SIGINT)  # still ignored while the process finishes
print(signal.getsignal(signal.SIGINT) is signal.default_int_handler)
"""
    done = run(script)
    assert done.returncode == 0, done.stderr
    assert done.stdout.split() == ["True", "True", "True", "SIGTERM", "False"]


@pytest.mark.parametrize("partial", ["ctypes", "struct"])
def test_guard_stops_cleanly_inside_an_import_of_what_it_flushes_with(partial: str) -> None:
    # signalled while ``ctypes`` (or ``struct``, which ctypes imports) is half imported: the
    # module is in sys.modules without its names; the stop is still clean, with its own code
    body = (
        "import types\n"
        "sys.modules.pop('ctypes', None)\n"
        f"sys.modules[{partial!r}] = types.ModuleType({partial!r})"
    )
    done = run(GUARDED.format(body=body, sig="SIGINT"))
    assert done.returncode == 130, done.stderr
    assert done.stderr == "probe: stopped by SIGINT while starting\n"
