"""The pool-of-bridges benchmark's code path at tiny size: two example controllers, each
bridged by its own ``param_bridge_node``, share one TuRPBO run (separate processes, as a user
starts them); both evaluate candidates, the bag verifies, and the same run with one worker
gives the same candidates, outcomes and episode returns. Nothing about time is asserted (the
benchmark prints the figures)."""

from __future__ import annotations

from pathlib import Path

from localpbo_ros.benchmarks.bridge_pool import Setup, differences, run_layout
from localpbo_ros.replay import verify

# 2 initial points and one batch of 4; 30-step trials (0.1 s) at the benchmark's rates
SETUP = Setup(budget=6, batch_size=4, episode_steps=30, domain=87, timeout_s=600.0)


def test_two_bridges_share_a_run_and_change_nothing(tmp_path: Path) -> None:
    two = run_layout(2, SETUP, tmp_path, "tiny")
    assert two.evaluations == SETUP.budget
    assert set(two.by_worker) == {"bridge_0", "bridge_1"}, two.by_worker
    assert all(n >= 1 for n in two.by_worker.values())
    assert sum(two.by_worker.values()) == SETUP.budget
    assert len(two.decisions_s) == 2  # the initial design's ask and the batch's
    report = verify(two.bag)
    assert report.ok and report.candidates_checked == SETUP.budget, report.format()

    one = run_layout(1, SETUP, tmp_path, "tiny")
    assert one.by_worker == {"bridge_0": SETUP.budget}
    assert verify(one.bag).ok
    assert differences(one.bag, two.bag) == []
