"""A pool of worker processes (as with ``ros2 run``): one worker hangs in an episode and is
then killed while holding candidates; the other takes them over, the run completes and its bag
verifies.

The hanging worker never publishes a result (``hanging_sim.py``), so the test does not depend
on where a signal lands relative to a result in flight."""

from __future__ import annotations

import subprocess
import time
from pathlib import Path

from localpbo_ros.bagtools import load_run
from localpbo_ros.replay import verify

from localpbo_msgs_py import CandidateMsg, EpisodeResult, EpisodeStatus, Status
from localpbo_msgs_py.bag import read_messages, summarize
from localpbo_msgs_py.topics import CANDIDATE, EPISODE_RESULT, STATUS

from .processes import host_env, start_node, stop_nodes

BUDGET = 48  # long enough that sim_1 is frozen well before the last batch
WORKER_TIMEOUT_S = 2.0


def _scan(bag: Path) -> tuple[dict[str, str], dict[int, str], set[int]]:
    """(node → worker id, candidate id → worker it was last assigned to, ids with an ok
    result) as recorded so far."""
    workers: dict[str, str] = {}
    assigned: dict[int, str] = {}
    results: set[int] = set()
    if not bag.exists():
        return workers, assigned, results
    for rec in read_messages(bag, topics=[STATUS.name, CANDIDATE.name, EPISODE_RESULT.name]):
        if rec.topic == STATUS.name:
            status = Status.decode(rec.message)
            if isinstance(status, Status) and "worker" in status.info:
                workers[status.node] = status.info["worker"]
        elif rec.topic == CANDIDATE.name:
            cand = CandidateMsg.decode(rec.message)
            if isinstance(cand, CandidateMsg) and cand.worker:
                assigned[cand.candidate_id] = cand.worker
        else:
            res = EpisodeResult.decode(rec.message)
            if isinstance(res, EpisodeResult) and res.status is EpisodeStatus.OK:
                results.add(res.candidate_id)
    return workers, assigned, results


def _wait(bag: Path, cond, what: str, limit: float = 120.0):
    deadline = time.monotonic() + limit
    while time.monotonic() < deadline:
        got = cond(*_scan(bag))
        if got:
            return got
        time.sleep(0.1)
    raise AssertionError(f"never saw {what} in the bag")


def test_killed_worker_process_is_taken_over(tmp_path: Path) -> None:
    env = host_env(98)
    bag = tmp_path / "pool.mcap"

    def start(node: str, *ros_args: str) -> subprocess.Popen[str]:
        if node.endswith(".py"):
            node = str(Path(__file__).with_name(node))
        return start_node(env, node, *ros_args)

    recorder = start("recorder_node", "-p", f"path:={bag}")
    oracle = start("oracle_node")
    sims = {
        "sim_0": start("sim_node", "-r", "__node:=sim_0"),
        "sim_1": start("hanging_sim.py", "-r", "__node:=sim_1"),
    }
    opt = None
    try:
        workers = _wait(bag, lambda w, a, r: w if {"sim_0", "sim_1"} <= set(w) else None, "workers")
        opt = start(
            "optimizer_node",
            *("-p", "algorithm:=sobol", "-p", "algorithm_options:='{\"batch_size\": 4}'"),
            *("-p", f"budget:={BUDGET}", "-p", "run_id:=pool", "-p", "min_subscribers:=2"),
            *("-p", "min_workers:=2", "-p", f"worker_timeout_s:={WORKER_TIMEOUT_S}"),
            *("-p", 'task_options:=\'{"episode_steps": 1000, "value_range": 50.0}\''),
        )
        victim = workers["sim_1"]
        # sim_1 hangs in its first episode; kill it after the worker timeout: whatever it
        # holds (that candidate, and any assigned while it still counted as live) only a
        # take-over answers
        _wait(bag, lambda w, a, r: victim in a.values(), "a candidate for sim_1")
        time.sleep(WORKER_TIMEOUT_S + 1.0)
        sims["sim_1"].kill()
        sims["sim_1"].wait(30)
        _, err = opt.communicate(timeout=180)
        assert opt.returncode == 0, err
    finally:
        if opt is not None and opt.poll() is None:
            opt.kill()
        if sims["sim_1"].poll() is None:
            sims["sim_1"].kill()
        codes = stop_nodes([recorder, oracle, sims["sim_0"]])
    assert codes == [0, 0, 0]
    assert summarize(bag).complete
    _, assigned, results = _scan(bag)
    assert results == set(range(BUDGET))
    # who began which episode (every worker announces the candidate before its episode):
    # each candidate once, except the one sim_1 hung in, which sim_0 ran again
    starts: dict[int, set[str]] = {}
    last_busy: dict[str, int] = {}
    for rec in read_messages(bag, topics=[STATUS.name]):
        status = Status.decode(rec.message)
        if isinstance(status, Status) and status.info.get("busy") and "worker" in status.info:
            cid = int(status.info["busy"])
            starts.setdefault(cid, set()).add(status.info["worker"])
            last_busy[status.info["worker"]] = cid
    assert set(starts) == set(range(BUDGET))
    hung = last_busy[workers["sim_1"]]
    assert {cid for cid, who in starts.items() if len(who) > 1} == {hung}
    assert starts[hung] == {workers["sim_0"], workers["sim_1"]}
    final = [
        st
        for st in (Status.decode(r.message) for r in read_messages(bag, topics=[STATUS.name]))
        if isinstance(st, Status) and st.node == "optimizer_node"
    ][-1]
    assert final.state == "done" and final.counters["reassigned"] >= 1
    assert final.counters["assigned"] >= BUDGET + 1
    # sim_1 took part (waited for above); after the take-over a candidate's last assignment
    # may be sim_0's for every candidate
    assert set(assigned.values()) <= {workers["sim_0"], workers["sim_1"]}
    run = load_run(bag)
    assert len(run.candidates) == BUDGET
    report = verify(bag)
    assert report.ok, report.format()
