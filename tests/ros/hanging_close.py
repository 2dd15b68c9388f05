"""A ``recorder_node`` whose clean-up never ends: ``close()`` blocks for good.

Run as a process (``python tests/ros/hanging_close.py --ros-args -p path:=...``) with
``entry.STOP_GRACE_S`` cut to two seconds, so a test can watch the stop watchdog act.
"""

from __future__ import annotations

import time

from localpbo_ros import entry
from localpbo_ros.recorder_node import RecorderNode


class HangingCloseRecorder(RecorderNode):
    """``RecorderNode`` whose ``close`` never returns."""

    def close(self) -> None:
        while True:
            time.sleep(3600.0)


if __name__ == "__main__":
    entry.STOP_GRACE_S = 2.0
    entry.run_node(HangingCloseRecorder, None, stop_when_finished=False)
