"""The nodes as separate processes (as with ``ros2 run``), DDS kept on this host by the
executables' defaults (the loopback/SHM Fast DDS profile): every socket of every node process
is bound to a loopback address while the run goes on."""

from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path

import psutil
from localpbo_ros.bagtools import load_run
from localpbo_ros.replay import verify

from localpbo_msgs_py import Status
from localpbo_msgs_py.bag import read_messages, summarize
from localpbo_msgs_py.topics import STATUS

from .processes import host_env, start_node, stop_nodes
from .test_dds_scope import non_loopback_sockets


def test_four_processes_complete_a_run(tmp_path: Path) -> None:
    env = host_env(57)
    bag = tmp_path / "mp.mcap"

    def start(node: str, *ros_args: str) -> subprocess.Popen[str]:
        return start_node(env, node, *ros_args)

    helpers = [
        start("recorder_node", "-p", f"path:={bag}"),
        start("sim_node"),
        start("oracle_node"),
    ]
    try:
        # start the optimizer once the recorder hears simulator and oracle (discovery done)
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline:
            heard = set()
            if bag.exists():
                for rec in read_messages(bag, topics=[STATUS.name]):
                    status = Status.decode(rec.message)
                    if isinstance(status, Status):
                        heard.add(status.node)
            if {"sim_node", "oracle_node"} <= heard:
                break
            time.sleep(0.1)
        opt = subprocess.run(
            [
                sys.executable,
                "-m",
                "localpbo_ros.optimizer_node",
                "--ros-args",
                "-p",
                "algorithm:=sobol",
                "-p",
                "budget:=8",
                "-p",
                "run_id:=mp",
                "-p",
                "min_subscribers:=2",
                "-p",
                'task_options:=\'{"episode_steps": 50, "value_range": 50.0}\'',
            ],
            env=env,
            capture_output=True,
            text=True,
            timeout=120,
        )
        assert opt.returncode == 0, opt.stderr
        # DDS stayed on this host: no node holds a socket on another address (default Fast
        # DDS would bind 0.0.0.0 and the host's external addresses)
        for proc in helpers:
            assert non_loopback_sockets(psutil.Process(proc.pid)) == []
    finally:
        codes = stop_nodes(helpers)
    assert codes == [0, 0, 0]
    assert summarize(bag).complete
    run = load_run(bag)
    assert run.config.run_id == "mp" and len(run.candidates) == 8
    report = verify(bag)
    assert report.ok, report.format()
