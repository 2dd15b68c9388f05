"""What a user of the executables sees: the optimizer says what its start waits for, and
every CLI verb piped into ``head`` ends quietly."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

COMMITTED_BAG = Path(__file__).resolve().parents[2] / "bags" / "swimmer_sobol_s0.mcap"


def test_optimizer_says_what_it_waits_for() -> None:
    env = {**os.environ, "ROS_AUTOMATIC_DISCOVERY_RANGE": "OFF", "PYTHONUNBUFFERED": "1"}
    cmd = [sys.executable, "-m", "localpbo_ros.optimizer_node", "--ros-args"]
    args = ["-p", "algorithm:=sobol", "-p", "min_subscribers:=2", "-p", "min_workers:=1"]
    proc = subprocess.Popen(
        [*cmd, *args], env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True
    )
    assert proc.stdout is not None
    lines: list[str] = []
    try:
        deadline = time.monotonic() + 60
        for line in proc.stdout:
            lines.append(line)
            if "waiting to start" in line or time.monotonic() > deadline:
                break
    finally:
        proc.send_signal(signal.SIGINT)
        out, _ = proc.communicate(timeout=30)
    lines.append(out)
    text = "".join(lines)
    assert (
        "waiting to start: /localpbo/candidate has 0 of 2 subscribers, "
        "/localpbo/duel_request 0 of 2 (min_subscribers); 0 of 1 pool workers heard "
        "(min_workers)" in text
    ), text[-3000:]
    assert text.count("waiting to start") == 1  # throttled: once per 5 s


VERBS = {
    "bag-info": ["localpbo", "bag-info", str(COMMITTED_BAG)],
    "bench": [
        "localpbo",
        *"bench --problem hartmann6 --algorithm sobol --budget 6 --seeds 0-1 --no-progress".split(),
    ],
    "python -m localpbo_ros.commands bag-info": [
        sys.executable,
        "-m",
        "localpbo_ros.commands",
        "bag-info",
        str(COMMITTED_BAG),
    ],
}


@pytest.mark.parametrize("verb", sorted(VERBS))
def test_a_closed_pipe_ends_a_verb_quietly(verb: str, tmp_path: Path) -> None:
    """``localpbo VERB | head -1``: head's one line, no traceback or complaint from the verb,
    which ends with 141 (128 + SIGPIPE) once it writes after head has gone (its output
    unbuffered, so its second write comes after head's exit), or 0 if it was done before."""
    argv = VERBS[verb]
    if argv[0] == "localpbo":
        argv = [str(Path(sys.executable).with_name("localpbo")), *argv[1:]]
    if verb == "bench":
        argv = [*argv, "--out", str(tmp_path)]
    env = {**os.environ, "ROS_AUTOMATIC_DISCOVERY_RANGE": "OFF", "PYTHONUNBUFFERED": "1"}
    shell = " ".join(f"'{a}'" for a in argv) + " | head -1"
    done = subprocess.run(
        ["bash", "-o", "pipefail", "-c", shell],
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert done.stdout.count("\n") == 1, done.stdout
    assert "Traceback" not in done.stderr, done.stderr
    assert "Broken pipe" not in done.stderr and "BrokenPipe" not in done.stderr, done.stderr
    assert "Exception ignored" not in done.stderr, done.stderr
    assert done.returncode in (0, 141), (done.returncode, done.stderr)
