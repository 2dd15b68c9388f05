"""DDS scope of the executables: by default a node process listens on loopback only."""

from __future__ import annotations

import ipaddress
import os
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager

import psutil
import pytest
from localpbo_ros import dds

from .processes import wait_ready

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
