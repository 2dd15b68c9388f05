"""Upper bounds on the serialized (CDR) size of any message the codecs accept.

A recorder or bridge can refuse anything larger without decoding it. The bounds follow from
the codecs' caps: ``MAX_THETA_LEN`` floats per θ, ``MAX_KEYVALUES`` KeyValue pairs per
DiagnosticStatus, ``MAX_TEXT`` characters per string field (counted as 4 UTF-8 bytes each, the
worst case) and ``MAX_CONFIG_BYTES`` of run-config JSON. Every string in CDR costs a 4-byte
length, its bytes, a terminating NUL and up to 3 bytes of alignment; ``FIXED`` covers the
encapsulation header, sequence lengths, integers and alignment of one message generously.
"""

from __future__ import annotations

from localpbo_msgs_py._validate import MAX_KEYVALUES, MAX_TEXT, MAX_THETA_LEN
from localpbo_msgs_py.run_config import MAX_CONFIG_BYTES
from localpbo_msgs_py.topics import ALL_TOPICS, TopicSpec

FIXED = 256
"""Bytes for everything but strings and arrays in one message (header, lengths, alignment)."""

TEXT_BYTES = 4 + 4 * MAX_TEXT + 1 + 3
"""Largest string field of at most ``MAX_TEXT`` characters, in CDR."""

THETA_MESSAGE_BYTES = FIXED + TEXT_BYTES + 8 * MAX_THETA_LEN
"""``Float64MultiArray``: one layout dimension (label) and at most ``MAX_THETA_LEN`` floats."""

DIAGNOSTIC_STATUS_BYTES = FIXED + 3 * TEXT_BYTES + MAX_KEYVALUES * 2 * TEXT_BYTES
"""``DiagnosticStatus``: name, message, hardware_id and ``MAX_KEYVALUES`` key/value pairs."""

DIAGNOSTIC_ARRAY_BYTES = FIXED + TEXT_BYTES + DIAGNOSTIC_STATUS_BYTES
"""``DiagnosticArray`` of the status topic: a header (frame id) and exactly one status."""

STRING_BYTES = FIXED + MAX_CONFIG_BYTES
"""``String`` holding the run config."""

BOUND_BY_TYPE = {
    "std_msgs/msg/Float64MultiArray": THETA_MESSAGE_BYTES,
    "diagnostic_msgs/msg/DiagnosticStatus": DIAGNOSTIC_STATUS_BYTES,
    "diagnostic_msgs/msg/DiagnosticArray": DIAGNOSTIC_ARRAY_BYTES,
    "std_msgs/msg/String": STRING_BYTES,
}


def max_message_bytes(spec: TopicSpec) -> int:
    """Largest serialized message a decoder accepts on ``spec``'s topic."""
    return BOUND_BY_TYPE[spec.type_name]


MAX_MESSAGE_BYTES = max(max_message_bytes(spec) for spec in ALL_TOPICS)
"""Largest serialized message a decoder accepts on any suite topic."""
