"""The nodes as separate processes (as with ``ros2 run``), DDS kept on this host by the
executables' defaults (LOCALHOST discovery range + the loopback/SHM Fast DDS profile)."""

from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path

from localpbo_ros.bagtools import load_run
from localpbo_ros.replay import verify

from localpbo_msgs_py import Status
from localpbo_msgs_py.bag import read_messages, summarize
from localpbo_msgs_py.topics import STATUS

from .processes import host_env, start_node, stop_nodes


def tx_packets() -> int:
    """Packets sent so far on every network interface except loopback."""
    total = 0
    for iface in Path("/sys/class/net").iterdir():
        if iface.name != "lo" and (iface / "statistics/tx_packets").is_file():
            total += int((iface / "statistics/tx_packets").read_text())
    return total


def test_four_processes_complete_a_run(tmp_path: Path) -> None:
    sent_before = tx_packets()
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
    finally:
        codes = stop_nodes(helpers)
    assert codes == [0, 0, 0]
    assert summarize(bag).complete
    run = load_run(bag)
    assert run.config.run_id == "mp" and len(run.candidates) == 8
    report = verify(bag)
    assert report.ok, report.format()
    # DDS stayed on this host: default Fast DDS discovery would multicast on every interface
    # several times in this window; allow 2 packets of unrelated host chatter
    assert tx_packets() - sent_before <= 2
