"""The nodes as separate processes (as with ``ros2 run``), DDS kept on this host by the
executables' defaults (the loopback/SHM Fast DDS profile): every socket of every node process
is bound to a loopback address while the run goes on."""

from __future__ import annotations

import subprocess
from pathlib import Path

import psutil
from localpbo_ros.bagtools import load_run
from localpbo_ros.replay import verify

from localpbo_msgs_py.bag import summarize

from .processes import host_env, run_sobol, start_node, stop_nodes, wait_heard
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
        wait_heard(bag, {"sim_node", "oracle_node"})
        opt = run_sobol(env, "mp", 8, timeout_s=120)
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
