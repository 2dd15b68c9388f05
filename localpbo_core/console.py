"""The ``localpbo`` executable: the stop guard first, then the CLI (:mod:`localpbo_core.cli`).

Exit codes on SIGINT/SIGTERM follow the shell's convention, 128 + the signal (130 for Ctrl-C,
143 for SIGTERM): while the command is starting (importing numpy, torch, rclpy) the process
ends at once with a one-line message (:func:`localpbo_core.stopping.guard_start`);
``localpbo run`` then stops cleanly (its bag finished, a controller's parameters restored, the
same codes); the other verbs keep Python's default handling, and a ``KeyboardInterrupt`` that
reaches the top ends the command with code 130 and a one-line message instead of a traceback.
"""

from __future__ import annotations

import os
import signal
from collections.abc import Sequence

from localpbo_core.stopping import guard_start, shell_code


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``localpbo`` console script."""
    guard_start("localpbo", shell_code)
    try:
        from localpbo_core.cli import main as cli_main
        from localpbo_core.pipes import quiet_on_closed_pipe

        return quiet_on_closed_pipe(lambda: cli_main(argv))  # `localpbo ... | head` ends quietly
    except KeyboardInterrupt:
        os.write(2, b"localpbo: interrupted\n")
        return shell_code(signal.SIGINT)
