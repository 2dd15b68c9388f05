"""``offered_qos_profiles`` channel metadata in the YAML form rosbag2 Jazzy writes.

rosbag2_storage ``qos.cpp`` (bag format version 9+) writes a YAML sequence of maps with keys, in
order: ``history``, ``depth``, ``reliability``, ``durability``, ``deadline``, ``lifespan``,
``liveliness``, ``liveliness_lease_duration``, ``avoid_ros_namespace_conventions``; policies as
the rmw strings (``keep_last``, ``reliable``, ``transient_local``, ``automatic``, ...) and
durations as ``{sec, nsec}``. An unset (zero) duration is what the middleware reports as
infinite, ``RMW_DURATION_INFINITE`` = ``{sec: 9223372036, nsec: 854775807}``.
"""

from __future__ import annotations

from collections.abc import Sequence
from enum import Enum
from typing import Any, TypeVar

import yaml
from rclpy.duration import Duration
from rclpy.qos import (
    DurabilityPolicy,
    HistoryPolicy,
    LivelinessPolicy,
    QoSProfile,
    ReliabilityPolicy,
)

INFINITE = {"sec": 9223372036, "nsec": 854775807}

_Policy = TypeVar("_Policy", bound=Enum)


def _rmw_names(policy: type[_Policy], *names: str) -> dict[_Policy, str]:
    """Each of ``names`` (rmw strings) by the member of ``policy`` it names in upper case."""
    return {policy[name.upper()]: name for name in names}


_HISTORY = _rmw_names(HistoryPolicy, "keep_last", "keep_all", "system_default")
_RELIABILITY = _rmw_names(ReliabilityPolicy, "reliable", "best_effort", "system_default")
_DURABILITY = _rmw_names(DurabilityPolicy, "volatile", "transient_local", "system_default")
_LIVELINESS = {
    **_rmw_names(LivelinessPolicy, "automatic", "manual_by_topic"),
    # SYSTEM_DEFAULT is what Fast DDS offers as automatic
    LivelinessPolicy.SYSTEM_DEFAULT: "automatic",
}


def _duration(value: Duration) -> dict[str, int]:
    ns = value.nanoseconds
    if ns <= 0:
        return dict(INFINITE)
    return {"sec": ns // 1_000_000_000, "nsec": ns % 1_000_000_000}


def profile_dict(qos: QoSProfile) -> dict[str, Any]:
    """One profile as the ordered mapping rosbag2 writes."""
    return {
        "history": _HISTORY[qos.history],
        "depth": int(qos.depth),
        "reliability": _RELIABILITY[qos.reliability],
        "durability": _DURABILITY[qos.durability],
        "deadline": _duration(qos.deadline),
        "lifespan": _duration(qos.lifespan),
        "liveliness": _LIVELINESS[qos.liveliness],
        "liveliness_lease_duration": _duration(qos.liveliness_lease_duration),
        "avoid_ros_namespace_conventions": bool(qos.avoid_ros_namespace_conventions),
    }


def offered_qos_yaml(profiles: Sequence[QoSProfile]) -> str:
    """The ``offered_qos_profiles`` metadata value for one channel (one entry per publisher)."""
    if not profiles:
        return ""
    return yaml.safe_dump(
        [profile_dict(p) for p in profiles], sort_keys=False, default_flow_style=False
    )


def parse_offered_qos(text: str) -> list[dict[str, Any]]:
    """Parse the metadata value back (for tests and bag-info)."""
    if not text:
        return []
    data = yaml.safe_load(text)
    if not isinstance(data, list):
        raise ValueError("offered_qos_profiles is not a YAML sequence")
    return data
