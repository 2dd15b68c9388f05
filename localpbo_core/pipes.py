"""A command whose reader goes away (``localpbo bag-info BAG | head -1``) ends quietly.

Python turns a write to a closed pipe into ``BrokenPipeError``; left alone it ends the command
with a traceback, and the interpreter's final flush of ``sys.stdout`` prints another error.
:func:`quiet_on_closed_pipe` follows the recipe of Python's documentation (``signal`` module,
"Note on SIGPIPE"): catch the error, point standard output at ``os.devnull`` so the final
flush has nowhere to fail, and end with 141 (128 + SIGPIPE, what a process killed by SIGPIPE
reports to the shell). SIGPIPE itself keeps Python's handling: restoring the default action
would kill a running ``localpbo run`` at its first write to a closed pipe, before it finishes
its bag.
"""

from __future__ import annotations

import os
import signal
import sys
from collections.abc import Callable

__all__ = ["CLOSED_PIPE_EXIT", "quiet_on_closed_pipe"]

CLOSED_PIPE_EXIT = 128 + int(signal.SIGPIPE)
"""Exit code of a command whose standard output was closed by its reader (141)."""


def quiet_on_closed_pipe(command: Callable[[], int]) -> int:
    """``command()``'s exit code, or :data:`CLOSED_PIPE_EXIT` (no traceback, no message)
    when its standard output is a pipe its reader closed."""
    try:
        try:
            code = command()
        finally:  # also on SystemExit (``--help``): a closed pipe shows here, not at exit
            sys.stdout.flush()
        return code
    except BrokenPipeError:
        devnull = os.open(os.devnull, os.O_WRONLY)
        try:
            os.dup2(devnull, sys.stdout.fileno())
        finally:
            os.close(devnull)
        return CLOSED_PIPE_EXIT
