"""DDS scope of the executables: by default a node process and a one-process ``localpbo run``
(plain, with the judge's page, with the example controller in the process or bridged to one in
another process) bind every socket on loopback; ``LOCALPBO_DDS_OPEN=1`` leaves DDS to the
user."""

from __future__ import annotations

import ipaddress
import json
import os
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import psutil
import pytest
from localpbo_examples.pid_controller_node import BRIDGE_SETTINGS
from localpbo_ros import dds

from .processes import interrupt, wait_ready

PID_SPACE = (
    Path(__file__).resolve().parents[2] / "ros_ws/src/localpbo_examples/config/pid_space.yaml"
)

DDS_VARIABLES = (
    "ROS_AUTOMATIC_DISCOVERY_RANGE",
    "ROS_LOCALHOST_ONLY",
    "FASTRTPS_DEFAULT_PROFILES_FILE",
    "FASTDDS_BUILTIN_TRANSPORTS",
    "LOCALPBO_DDS_OPEN",
)


@contextmanager
def node_process(extra_env: dict[str, str]) -> Iterator[psutil.Process]:
    """``sim_node`` in its own process, yielded once it logged ``ready`` and announced itself."""
    env = {k: v for k, v in os.environ.items() if k not in DDS_VARIABLES}
    env["ROS_DOMAIN_ID"] = "61"
    env.update(extra_env)
    proc = subprocess.Popen(
        [sys.executable, "-m", "localpbo_ros.sim_node"],
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
    )
    try:
        wait_ready(proc)
        time.sleep(2.0)  # let discovery announce (and open every socket it will open)
        yield psutil.Process(proc.pid)
        proc.send_signal(signal.SIGINT)
        assert proc.wait(20) == 0
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()


def is_loopback(address: str) -> bool:
    return ipaddress.ip_address(address.split("%")[0]).is_loopback


def non_loopback_sockets(process: psutil.Process) -> list[str]:
    """Inet sockets whose local address is not loopback.

    A socket connected to a loopback peer has a loopback local address too, so this covers
    listening, bound and connected sockets alike.
    """
    return [
        f"{conn.type.name} {conn.laddr.ip}:{conn.laddr.port} -> {conn.raddr}"
        for conn in process.net_connections(kind="inet")
        if not is_loopback(conn.laddr.ip)
    ]


@pytest.mark.parametrize(
    "user_env",
    [
        {},
        {"ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST"},
        {"ROS_AUTOMATIC_DISCOVERY_RANGE": "SUBNET", "ROS_LOCALHOST_ONLY": "1"},
    ],
    ids=["default", "range-localhost", "range-subnet"],
)
def test_node_process_listens_on_loopback_only(user_env: dict[str, str]) -> None:
    with node_process(user_env) as process:
        sockets = process.net_connections(kind="inet")
        assert any(c.laddr.ip == "127.0.0.1" for c in sockets), sockets  # DDS is up
        assert non_loopback_sockets(process) == []


def test_opt_in_leaves_dds_to_the_user() -> None:
    # the control case: the same check flags what LOCALHOST discovery range alone opens
    env = {"LOCALPBO_DDS_OPEN": "1", "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST"}
    with node_process(env) as process:
        assert non_loopback_sockets(process) != []


def test_host_scope_environment(monkeypatch: pytest.MonkeyPatch) -> None:
    for name in DDS_VARIABLES:
        monkeypatch.delenv(name, raising=False)
    monkeypatch.setenv("ROS_LOCALHOST_ONLY", "1")
    dds.host_scope()
    assert os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] == "SYSTEM_DEFAULT"
    assert os.environ["FASTRTPS_DEFAULT_PROFILES_FILE"] == str(dds.PROFILE_FILE)
    assert "ROS_LOCALHOST_ONLY" not in os.environ
    monkeypatch.setenv("ROS_AUTOMATIC_DISCOVERY_RANGE", "OFF")
    dds.host_scope()
    assert os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] == "OFF"
    for name in DDS_VARIABLES:
        monkeypatch.delenv(name, raising=False)
    monkeypatch.setenv("LOCALPBO_DDS_OPEN", "1")
    monkeypatch.setenv("ROS_AUTOMATIC_DISCOVERY_RANGE", "SUBNET")
    dds.host_scope()
    assert os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] == "SUBNET"
    assert "FASTRTPS_DEFAULT_PROFILES_FILE" not in os.environ


LOCALPBO = str(Path(sys.executable).with_name("localpbo"))
SMALL = ["--algorithm", "sobol", "--task-options", '{"episode_steps": 50, "value_range": 50}']


@contextmanager
def process(cmd: list[str], extra_env: dict[str, str], domain: int) -> Iterator[psutil.Process]:
    """``cmd`` on ``domain``, yielded once DDS has been up for 2 s (discovery announced,
    every socket it will open opened); stopped with SIGINT afterwards."""
    env = {k: v for k, v in os.environ.items() if k not in DDS_VARIABLES}
    env["ROS_DOMAIN_ID"] = str(domain)
    env.update(extra_env)
    proc = subprocess.Popen(cmd, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        handle = psutil.Process(proc.pid)
        deadline = time.monotonic() + 120
        while not any(c.type.name == "SOCK_DGRAM" for c in handle.net_connections("inet")):
            assert proc.poll() is None, f"{cmd} ended with {proc.returncode}"
            assert time.monotonic() < deadline, f"{cmd}: no DDS socket within 120 s"
            time.sleep(0.1)
        time.sleep(2.0)
        assert proc.poll() is None, f"{cmd} ended with {proc.returncode}"
        yield handle
    finally:
        if proc.poll() is None:
            interrupt(proc, 60)


def run_cmd(tmp_path: Path, *args: str) -> list[str]:
    bag = str(tmp_path / "scope.mcap")
    return [LOCALPBO, "run", *args, "--budget", "400", "--bag", bag, "--no-progress"]


RUNS = {
    "plain": [*SMALL],
    "human": ["--oracle", "human", "--algorithm", "sobol"],
    "example-controller": ["--space", str(PID_SPACE), "--example-controller", *SMALL[:2]],
}


@pytest.mark.parametrize("kind", list(RUNS))
def test_one_process_run_binds_loopback_only(kind: str, tmp_path: Path) -> None:
    args = RUNS[kind]
    if kind == "human":
        args = [*args, "--judge", json.dumps({"state_dir": str(tmp_path / "judge")})]
    with process(run_cmd(tmp_path, *args), {}, 55) as handle:
        sockets = handle.net_connections(kind="inet")
        assert any(c.laddr.ip == "127.0.0.1" for c in sockets), sockets
        assert non_loopback_sockets(handle) == []


def test_bridged_run_and_its_controller_bind_loopback_only(tmp_path: Path) -> None:
    controller = [sys.executable, "-m", "localpbo_examples.pid_controller_node"]
    with process(controller, {}, 56) as target:
        cmd = run_cmd(tmp_path, "--space", str(PID_SPACE), "--bridge", json.dumps(BRIDGE_SETTINGS))
        with process([*cmd, *SMALL[:2]], {}, 56) as run:
            assert non_loopback_sockets(run) == []
            assert non_loopback_sockets(target) == []


def test_one_process_run_opt_in_leaves_dds_to_the_user(tmp_path: Path) -> None:
    # the control case: with the opt-in and no range, DDS binds on every interface
    with process(run_cmd(tmp_path, *SMALL), {"LOCALPBO_DDS_OPEN": "1"}, 57) as handle:
        assert non_loopback_sockets(handle) != []
