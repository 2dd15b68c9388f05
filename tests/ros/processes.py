"""Node executables as subprocesses, for tests of what a ``ros2 run`` user sees."""

from __future__ import annotations

import subprocess


def wait_ready(proc: subprocess.Popen[str]) -> list[str]:
    """Read the node's output until it logs ``<name> ready``; return the lines read.

    Fails (with the output) if the process ends first. The process must have been started
    with ``stdout=PIPE, stderr=STDOUT, text=True``.
    """
    assert proc.stdout is not None
    lines = []
    for line in proc.stdout:
        lines.append(line)
        if " ready" in line:
            return lines
    raise AssertionError("node ended before it was ready:\n" + "".join(lines))
