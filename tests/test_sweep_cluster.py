"""``localpbo sweep --address``: a sweep submitted to a Ray cluster started apart (``ray start
--head`` on the loopback address, token authentication) runs, resumes and stores the runs the
in-process sweep stores; the cluster serves on the loopback address only, and the sweep leaves
it running (it is the user's)."""

from __future__ import annotations

import os
import secrets
import signal
import socket
import subprocess
import sys
import tempfile
import textwrap
import time
from collections.abc import Iterator
from pathlib import Path

import psutil
import pytest

from localpbo_core import ray_cleanup
from localpbo_core.experiments import load_spec
from localpbo_core.sweep import sweep
from tests.test_sweep import assert_same_runs

RAY = str(Path(sys.executable).with_name("ray"))


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


@pytest.fixture(scope="module")
def cluster() -> Iterator[tuple[str, dict[str, str], Path]]:
    """A one-node Ray cluster as docs/reproducing.md starts it: its address, the environment
    a client needs (the token) and its folder; stopped by its folder afterwards (``ray stop``
    would stop every Ray of this machine)."""
    folder = Path(tempfile.mkdtemp(prefix="lpbo-rc-", dir="/tmp"))  # Ray's socket paths are short
    env = {
        **os.environ,
        "RAY_AUTH_MODE": "token",
        "RAY_AUTH_TOKEN": secrets.token_hex(32),
        "RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER": "0",  # Ray's single-host mode: loopback only
    }
    port = _free_port()
    head = [RAY, "start", "--head", "--node-ip-address=127.0.0.1", f"--port={port}"]
    head += ["--num-cpus=2", "--include-dashboard=false", f"--temp-dir={folder}"]
    head += ["--disable-usage-stats"]
    started = subprocess.run(head, env=env, capture_output=True, text=True, timeout=120)
    try:
        assert started.returncode == 0, started.stdout + started.stderr
        yield f"127.0.0.1:{port}", env, folder
    finally:
        ray_cleanup.clean(folder, ray_cleanup.WATCHDOG_GRACE_S)


def _sweep(out: Path, address: str, env: dict[str, str], *extra: str) -> str:
    cmd = [sys.executable, "-m", "localpbo_core.cli", "sweep", "tiny", "--out", str(out)]
    cmd += ["--address", address, "--no-progress", *extra]
    done = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stdout + done.stderr
    return done.stdout


def test_a_sweep_on_a_cluster_runs_resumes_and_stores_the_same_runs(cluster, tmp_path) -> None:
    address, env, folder = cluster
    spec = load_spec("tiny")
    reference = tmp_path / "reference"
    assert not sweep(spec, reference, in_process=True, progress=False).failed
    out = tmp_path / "cluster"
    assert "2 runs finished, 0 already stored, 0 failed, 2 left" in _sweep(
        out, address, env, "--max-runs", "2"
    )
    assert "2 runs finished, 2 already stored, 0 failed, 0 left" in _sweep(out, address, env)
    assert_same_runs(spec, out, reference)
    holders = ray_cleanup.holders(folder)
    assert holders, "the sweep stopped the cluster it was given"
    for pid in holders:  # every server of the cluster on the loopback address
        try:
            listening = [
                c.laddr for c in psutil.Process(pid).net_connections() if c.status == "LISTEN"
            ]
        except psutil.NoSuchProcess:
            continue
        for laddr in listening:
            assert laddr.ip in ("127.0.0.1", "::ffff:127.0.0.1", "::1"), (pid, laddr)


def test_a_client_without_the_token_is_refused(cluster, tmp_path) -> None:
    address, env, _ = cluster
    cmd = [sys.executable, "-m", "localpbo_core.cli", "sweep", "tiny", "--out", str(tmp_path)]
    cmd += ["--address", address, "--no-progress", "--max-runs", "1"]
    stranger = {k: v for k, v in env.items() if k != "RAY_AUTH_TOKEN"}
    done = subprocess.run(cmd, env=stranger, capture_output=True, text=True, timeout=300)
    assert done.returncode != 0
    assert not list(tmp_path.glob("runs/*.json.gz"))


def test_an_address_where_nothing_listens_is_refused_at_once(tmp_path) -> None:
    port = _free_port()
    cmd = [sys.executable, "-m", "localpbo_core.cli", "sweep", "tiny", "--out", str(tmp_path)]
    done = subprocess.run(
        [*cmd, "--address", f"127.0.0.1:{port}", "--no-progress"],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == 2
    assert f"--address: no Ray cluster answers at 127.0.0.1:{port}" in done.stderr


def test_a_stop_while_ray_starts_ends_the_sweep_if_ray_does_not_return() -> None:
    """Ctrl-C or SIGTERM while Ray starts is acted on once ``ray.init`` returns; if it does not
    return within ``STOP_WAIT_S`` (here 1 s), or a second signal comes, the process ends at
    once with 130. (A ``ray.init`` blocked inside Ray's C++ client never lets Python's signal
    handlers run: there only SIGKILL helps; docs/reproducing.md says so.)"""
    script = textwrap.dedent(
        """
        import sys, time
        from localpbo_core import sweep
        sweep.STOP_WAIT_S = 1.0
        with sweep._stops_deferred(True):
            print("inside", flush=True)
            for _ in range(600):
                time.sleep(0.1)  # a start that does not return
        print("left the block", flush=True)
        """
    )
    for signals in ([signal.SIGTERM], [signal.SIGINT, signal.SIGINT]):
        proc = subprocess.Popen(
            [sys.executable, "-c", script],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        assert proc.stdout is not None and proc.stdout.readline() == "inside\n"
        sent = time.monotonic()
        for signum in signals:
            proc.send_signal(signum)
            time.sleep(0.2)
        out, err = proc.communicate(timeout=30)
        assert proc.returncode == 130, err
        assert time.monotonic() - sent < (5.0 if len(signals) == 1 else 1.5)
        assert "interrupted while Ray was starting" in err and "left the block" not in out
