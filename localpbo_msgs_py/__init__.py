"""localpbo message schemas and codecs onto ``common_interfaces`` types, and the MCAP bag I/O.

No custom rosidl package (so any ROS 2 install, C++ included, reads the topics with the stock
``common_interfaces``): θ travels as ``std_msgs/msg/Float64MultiArray``;
episode results and duels as ``diagnostic_msgs/msg/DiagnosticStatus`` KeyValue records; the run
config as JSON in ``std_msgs/msg/String``; status as ``diagnostic_msgs/msg/DiagnosticArray``.
Every ``decode`` validates strictly and returns a :class:`DecodeError` (field, reason, problem)
instead of raising.
"""

from localpbo_msgs_py.errors import DecodeError, DecodeReason, FieldError, Result, is_error
from localpbo_msgs_py.records import (
    DuelOutcome,
    DuelRequest,
    EpisodeResult,
    EpisodeStatus,
    OutcomeKind,
)
from localpbo_msgs_py.run_config import RunConfig
from localpbo_msgs_py.status import Status
from localpbo_msgs_py.theta import CandidateMsg, Incumbent

__all__ = [
    "CandidateMsg",
    "DecodeError",
    "DecodeReason",
    "DuelOutcome",
    "DuelRequest",
    "EpisodeResult",
    "EpisodeStatus",
    "FieldError",
    "Incumbent",
    "OutcomeKind",
    "Result",
    "RunConfig",
    "Status",
    "is_error",
]
