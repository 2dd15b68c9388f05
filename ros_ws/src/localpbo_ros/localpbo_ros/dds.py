"""DDS scope: this host only unless the user opts in.

* Separate processes (``ros2 run``, and ``localpbo run`` bridged to a controller in another
  process): the executables use the Fast DDS profile
  ``localhost_only.xml`` shipped with this package (unless ``FASTRTPS_DEFAULT_PROFILES_FILE``
  is already set) with ``ROS_AUTOMATIC_DISCOVERY_RANGE=SYSTEM_DEFAULT``, so that the profile
  alone decides: UDPv4 restricted to 127.0.0.1 plus shared memory, built-in transports off,
  discovery and data on 127.0.0.1 unicast locators, peers announced to 127.0.0.1, no
  multicast. Every socket of a node process is then bound to 127.0.0.1.
  ``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST`` (and the deprecated ``ROS_LOCALHOST_ONLY=1``)
  would not do: with it rmw_fastrtps adds a UDPv4 transport of its own, which binds sockets on
  0.0.0.0 and on the host's external addresses. ``OFF`` is kept when set (still loopback-only,
  but processes do not discover each other).
* In one process (``localpbo run``, ``make demo``, ``--oracle human``): the same profile with
  ``ROS_AUTOMATIC_DISCOVERY_RANGE=OFF`` (unless the user chose a range): the nodes share one
  ``Context`` and still connect; no other process discovers them, and the few sockets the
  participant opens are bound to 127.0.0.1 (``OFF`` alone would bind them on 0.0.0.0 and on
  the host's external addresses). A user who sets another range makes the run visible to
  processes on this host (e.g. ``ros2 topic echo``), still on loopback.
* To open to a network: set ``LOCALPBO_DDS_OPEN=1`` (every executable then leaves the
  environment alone) and choose ``ROS_AUTOMATIC_DISCOVERY_RANGE=SUBNET`` and a
  ``ROS_DOMAIN_ID`` yourself.

Environment variables are read when the first node is created, so call these before
``rclpy.init``.
"""

from __future__ import annotations

import os
from pathlib import Path

PROFILE_FILE = Path(__file__).with_name("localhost_only.xml")
OPEN_VARIABLE = "LOCALPBO_DDS_OPEN"
"""Set to ``1`` to leave the DDS environment to the user (network use)."""


def in_process_scope() -> None:
    """Keep all traffic inside this process, on loopback sockets (unless the user set a range:
    then this host; or ``LOCALPBO_DDS_OPEN=1``: the user's environment)."""
    if os.environ.get(OPEN_VARIABLE) == "1":
        return
    os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "OFF")
    host_scope()


def host_scope() -> None:
    """Keep traffic on this host for multi-process use (unless ``LOCALPBO_DDS_OPEN=1``)."""
    if os.environ.get(OPEN_VARIABLE) == "1":
        return
    if not PROFILE_FILE.is_file():
        raise FileNotFoundError(
            f"{PROFILE_FILE} is missing (package data of localpbo_ros); reinstall, or set "
            f"FASTRTPS_DEFAULT_PROFILES_FILE yourself, or {OPEN_VARIABLE}=1"
        )
    if os.environ.get("ROS_AUTOMATIC_DISCOVERY_RANGE") != "OFF":
        os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "SYSTEM_DEFAULT"
    os.environ.pop("ROS_LOCALHOST_ONLY", None)
    os.environ.setdefault("FASTRTPS_DEFAULT_PROFILES_FILE", str(PROFILE_FILE))
