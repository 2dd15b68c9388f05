"""DDS scope (DESIGN.md §4, §8): this host only unless the user opts in.

* In one process (``localpbo run``, tests): ``ROS_AUTOMATIC_DISCOVERY_RANGE=OFF`` — the nodes
  share one ``Context`` and still connect; nothing leaves the process.
* Separate processes (``ros2 run``): the executables default to
  ``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST`` and, unless ``FASTRTPS_DEFAULT_PROFILES_FILE``
  is already set, the Fast DDS profile ``localhost_only.xml`` shipped with this package
  (UDPv4 whitelisted to 127.0.0.1 plus shared memory, built-in transports off).
* To open to a network: set ``LOCALPBO_DDS_OPEN=1`` (the executables then leave the
  environment alone) and choose ``ROS_AUTOMATIC_DISCOVERY_RANGE=SUBNET`` and a
  ``ROS_DOMAIN_ID`` yourself.

Environment variables are read when the first node is created, so call these before
``rclpy.init``.
"""

from __future__ import annotations

import os
from pathlib import Path

PROFILE_FILE = Path(__file__).with_name("localhost_only.xml")


def in_process_scope() -> None:
    """Keep all traffic inside this process (unless the user set a range)."""
    os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "OFF")


def host_scope() -> None:
    """Keep traffic on this host for multi-process use (unless LOCALPBO_DDS_OPEN=1)."""
    if os.environ.get("LOCALPBO_DDS_OPEN") == "1":
        return
    os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    if not PROFILE_FILE.is_file():
        raise FileNotFoundError(
            f"{PROFILE_FILE} is missing (package data of localpbo_ros); reinstall, or set "
            "FASTRTPS_DEFAULT_PROFILES_FILE yourself, or LOCALPBO_DDS_OPEN=1"
        )
    os.environ.setdefault("FASTRTPS_DEFAULT_PROFILES_FILE", str(PROFILE_FILE))
