"""A run of the four node processes while a hostile peer on the same host floods every suite
topic with forged but well-formed messages (tests/ros/flooder.py): the run completes, no
episode runs for a forged candidate, the bag holds every message the run published (verify
OK) and apart from the foreign traffic, and bag-info shows the counters."""

from __future__ import annotations

import signal
import subprocess
import sys
import time
from pathlib import Path

from localpbo_ros.commands import main as commands_main
from localpbo_ros.completeness import last_statuses
from localpbo_ros.replay import verify

from localpbo_msgs_py.bag import summarize

from .processes import host_env, run_sobol, start_node, stop_nodes, wait_heard

FLOODER = str(Path(__file__).with_name("flooder.py"))
BUDGET = 30
FLOOD_RATE = 300
"""Forged messages per second: what the nodes keep up with on a loaded 2-core machine (a
flood beyond what a node can decode starves it; see the robustness section of the ROS
package's README)."""


def test_a_flooded_run_completes_with_its_whole_record(tmp_path: Path, capsys) -> None:
    env = host_env(80)
    bag = tmp_path / "flooded.mcap"
    helpers = [
        start_node(env, "recorder_node", "-p", f"path:={bag}", "-p", "max_foreign_bytes:=2000000"),
        start_node(env, "sim_node"),
        start_node(env, "oracle_node"),
    ]
    flooder = subprocess.Popen(
        [sys.executable, FLOODER, "hp", "600", str(FLOOD_RATE)],
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        wait_heard(bag, {"sim_node", "oracle_node"})
        time.sleep(2.0)  # the flood is on before the run starts
        opt = run_sobol(env, "hp", BUDGET, timeout_s=300)
        assert opt.returncode == 0, opt.stderr
        time.sleep(1.5)  # the helpers' last status heartbeats
        flooding_to_the_end = flooder.poll() is None  # its 600 s are not over
    finally:
        flooder.send_signal(signal.SIGINT)
        out, err = flooder.communicate(timeout=30)
        codes = stop_nodes(helpers)
    assert flooder.returncode == 0, err
    assert codes == [0, 0, 0]
    sent = int(out.split()[-1])
    # the flood ran all along: the flooder outlived the run, and it sent more than the run's
    # ids allow from the start (how many depends on the CPU a loaded machine gives it)
    assert flooding_to_the_end and sent > FLOOD_RATE, out
    report = verify(bag)
    assert report.ok, report.format()
    assert report.candidates_checked == BUDGET
    statuses = last_statuses(bag, "hp")
    sim, oracle = statuses["sim_node"], statuses["oracle_node"]
    assert sim.counters["episodes"] == BUDGET  # not one forged episode
    assert sim.counters["dropped_id_out_of_range"] > 0
    assert oracle.counters["dropped_id_out_of_range"] > 0
    summary = summarize(bag)
    counts = summary.recorder_counts()
    assert counts["foreign_id_out_of_range"] > 0 and counts["foreign_wrong_run"] > 0
    assert commands_main(["bag-info", str(bag)]) == 0
    out = capsys.readouterr().out
    assert "foreign:" in out and "dropped_id_out_of_range" in out
    print(out)
