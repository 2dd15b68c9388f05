"""Helpers for schemas carried by ``diagnostic_msgs/msg/DiagnosticStatus`` KeyValue pairs."""

from __future__ import annotations

from collections.abc import Mapping

from diagnostic_msgs.msg import DiagnosticStatus, KeyValue

from localpbo_msgs_py._guard import check_type
from localpbo_msgs_py._validate import check_text, keyvalues_to_dict
from localpbo_msgs_py.errors import DecodeReason, FieldError

STATUS_TYPE_NAME = "diagnostic_msgs/msg/DiagnosticStatus"

LEVEL_OK = 0
LEVEL_WARN = 1
LEVEL_ERROR = 2
LEVEL_STALE = 3


def level_byte(level: int) -> bytes:
    """DiagnosticStatus.level is a ``byte`` field: rclpy wants a length-1 ``bytes``."""
    return bytes([level])


def level_int(value: object) -> int:
    """Read DiagnosticStatus.level as an int whatever rclpy hands back (bytes or int)."""
    if isinstance(value, bytes | bytearray) and len(value) == 1:
        return value[0]
    if isinstance(value, int) and not isinstance(value, bool):
        return value
    raise FieldError("level", DecodeReason.MALFORMED, f"unreadable level {value!r}")


def make_status(
    name: str, level: int, message: str, values: Mapping[str, str], hardware_id: str = ""
) -> DiagnosticStatus:
    """Build a DiagnosticStatus; ``values`` keep their insertion order."""
    msg = DiagnosticStatus()
    msg.level = level_byte(level)
    msg.name = name
    msg.message = message
    msg.hardware_id = hardware_id
    msg.values = [KeyValue(key=k, value=v) for k, v in values.items()]
    return msg


def read_status(msg: object, name: str) -> tuple[int, str, dict[str, str]]:
    """Check type and ``name``; return (level, message, values-as-dict)."""
    check_type(msg, DiagnosticStatus, STATUS_TYPE_NAME)
    assert isinstance(msg, DiagnosticStatus)
    if msg.name != name:
        raise FieldError("name", DecodeReason.MALFORMED, f"is {msg.name[:80]!r}, expected {name!r}")
    check_text(msg.message, "message")
    check_text(msg.hardware_id, "hardware_id")
    return level_int(msg.level), msg.message, keyvalues_to_dict(msg.values)
