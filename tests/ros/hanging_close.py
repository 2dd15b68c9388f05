"""A ``recorder_node`` whose clean-up is slow: ``close()`` sleeps ``CLOSE_SLEEP_S`` seconds
(environment; default: for good) and declares ``close_timeout_s`` = ``CLOSE_TIMEOUT_S``
(default 0).

Run as a process (``python tests/ros/hanging_close.py --ros-args -p path:=...``) with
``entry.STOP_GRACE_S`` cut to two seconds, so a test can watch the stop watchdog act.
"""

from __future__ import annotations

import os
import time

from localpbo_ros import entry
from localpbo_ros.recorder_node import RecorderNode


class SlowCloseRecorder(RecorderNode):
    """``RecorderNode`` whose ``close`` sleeps before finishing the bag."""

    close_timeout_s = float(os.environ.get("CLOSE_TIMEOUT_S", "0"))

    def close(self) -> None:
        sleep_s = float(os.environ.get("CLOSE_SLEEP_S", "inf"))
        end = time.monotonic() + sleep_s
        while time.monotonic() < end:
            time.sleep(min(1.0, end - time.monotonic()))
        super().close()


if __name__ == "__main__":
    entry.STOP_GRACE_S = 2.0
    entry.run_node(SlowCloseRecorder, None, stop_when_finished=False)
