"""A ``sim_node`` whose first episode never ends: a worker that hangs mid-episode.

Run as a process (``python tests/ros/hanging_sim.py --ros-args -r __node:=sim_1``). It joins
the pool like ``sim_node``, announces its first candidate as busy, then blocks in the episode:
it never publishes a result, so only a take-over by another worker can answer what it holds.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np
from localpbo_ros.entry import run_node
from localpbo_ros.sim_node import SimNode

from localpbo_msgs_py import RunConfig


def _hang(config: RunConfig, candidate_id: int, theta: np.ndarray) -> float:
    while True:
        time.sleep(3600.0)


class HangingSimNode(SimNode):
    """``SimNode`` with an evaluator that never returns."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(evaluator=_hang, **kwargs)


if __name__ == "__main__":
    run_node(HangingSimNode, None, stop_when_finished=False)
