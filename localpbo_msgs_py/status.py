"""Node status and drop counters on ``diagnostic_msgs/msg/DiagnosticArray``.

One DiagnosticArray per report, holding exactly one DiagnosticStatus:

* ``header.stamp``: report time (``stamp_ns``); ``header.frame_id``: ``""``;
* ``status[0].name``: ``"localpbo/<node>"``; ``level``: 0 OK, 1 WARN, 2 ERROR, 3 STALE;
  ``message``: free text; ``hardware_id``: ``""``;
* ``status[0].values``: ``run_id``, ``node``, ``state`` (``[a-z][a-z0-9_]*``, e.g. ``running``,
  ``done``, ``failed``), then ``count.<name>`` = non-negative integer for each counter (e.g.
  ``count.dropped_wrong_run``, ``count.duels_done``) and ``info.<name>`` = text for each info item.
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from dataclasses import dataclass, field

from diagnostic_msgs.msg import DiagnosticArray

from localpbo_msgs_py._diag import LEVEL_STALE, make_status, read_status
from localpbo_msgs_py._guard import check_type, guarded
from localpbo_msgs_py._validate import (
    KEY_PATTERN,
    check_expected_run,
    check_id,
    check_run_id,
    check_text,
    parse_id,
    require_keys,
    unexpected_key,
)
from localpbo_msgs_py.errors import DecodeError, DecodeReason, FieldError

TYPE_NAME = "diagnostic_msgs/msg/DiagnosticArray"
NAME_PATTERN = re.compile(r"[a-z][a-z0-9_]{0,63}")


def _check_name(value: object, field_name: str) -> str:
    if not isinstance(value, str) or NAME_PATTERN.fullmatch(value) is None:
        shown = value[:80] if isinstance(value, str) else value
        raise FieldError(
            field_name,
            DecodeReason.MALFORMED,
            f"{shown!r} is not a name matching [a-z][a-z0-9_]{{0,63}}",
        )
    return value


@dataclass(frozen=True)
class Status:
    """A node's state and counters (topic ``/localpbo/status``)."""

    run_id: str
    node: str
    state: str
    level: int = 0
    message: str = ""
    counters: Mapping[str, int] = field(default_factory=dict)
    info: Mapping[str, str] = field(default_factory=dict)
    stamp_ns: int = 0

    def __post_init__(self) -> None:
        check_run_id(self.run_id)
        _check_name(self.node, "node")
        _check_name(self.state, "state")
        if isinstance(self.level, bool) or self.level not in range(LEVEL_STALE + 1):
            raise FieldError(
                "level", DecodeReason.OUT_OF_BOUNDS, f"must be 0..3, got {self.level!r}"
            )
        check_text(self.message, "message")
        check_id(self.stamp_ns, "stamp_ns")
        for k, n in self.counters.items():
            if not isinstance(k, str) or KEY_PATTERN.fullmatch(k) is None:
                raise FieldError("counters", DecodeReason.MALFORMED, f"bad counter name {k!r}")
            check_id(n, f"count.{k}")
        for k, t in self.info.items():
            if not isinstance(k, str) or KEY_PATTERN.fullmatch(k) is None:
                raise FieldError("info", DecodeReason.MALFORMED, f"bad info name {k!r}")
            check_text(t, f"info.{k}")
        object.__setattr__(self, "counters", dict(self.counters))
        object.__setattr__(self, "info", dict(self.info))

    def encode(self) -> DiagnosticArray:
        """The ROS message."""
        values = {"run_id": self.run_id, "node": self.node, "state": self.state}
        values.update({f"count.{k}": str(n) for k, n in self.counters.items()})
        values.update({f"info.{k}": t for k, t in self.info.items()})
        msg = DiagnosticArray()
        msg.header.stamp.sec = self.stamp_ns // 1_000_000_000
        msg.header.stamp.nanosec = self.stamp_ns % 1_000_000_000
        msg.status = [make_status(f"localpbo/{self.node}", self.level, self.message, values)]
        return msg

    @classmethod
    def decode(cls, msg: object, *, expected_run_id: str | None = None) -> Status | DecodeError:
        """Validate and decode (exactly one DiagnosticStatus expected)."""

        def body() -> Status:
            check_type(msg, DiagnosticArray, TYPE_NAME)
            assert isinstance(msg, DiagnosticArray)
            if len(msg.status) != 1:
                raise FieldError(
                    "status",
                    DecodeReason.MALFORMED,
                    f"must hold exactly 1 entry, has {len(msg.status)}",
                )
            entry = msg.status[0]
            node_key = next((kv.value for kv in entry.values if kv.key == "node"), "")
            node = _check_name(node_key, "node")
            level, message, v = read_status(entry, f"localpbo/{node}")
            require_keys(v, ("run_id", "node", "state"), optional=None)
            run_id = check_run_id(v["run_id"])
            check_expected_run(run_id, expected_run_id)
            counters: dict[str, int] = {}
            info: dict[str, str] = {}
            for key, text in v.items():
                if key in ("run_id", "node", "state"):
                    continue
                prefix, _, name = key.partition(".")
                if prefix == "count" and KEY_PATTERN.fullmatch(name):
                    counters[name] = parse_id(text, key)
                elif prefix == "info" and KEY_PATTERN.fullmatch(name):
                    info[name] = text
                else:
                    raise unexpected_key(key, key)
            stamp = msg.header.stamp
            return cls(
                run_id,
                node,
                v["state"],
                level,
                message,
                counters,
                info,
                stamp.sec * 1_000_000_000 + stamp.nanosec if stamp.sec >= 0 else -1,
            )

        return guarded("status", body)
