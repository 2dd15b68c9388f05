"""Default topic names, message types and QoS profiles shared by the nodes and the recorder.

All topics are reliable (a lost duel outcome would stall the run). Event topics keep the last
``EVENT_DEPTH`` messages and are volatile; state-like topics (incumbent, run config) are
transient-local with depth 1 so a late joiner receives the latest value. A transient-local
publisher also serves volatile subscribers; a transient-local subscriber does not connect to a
volatile publisher.
"""

from __future__ import annotations

from dataclasses import dataclass

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from std_msgs.msg import Float64MultiArray, String

EVENT_DEPTH = 100
"""History depth of event topics (candidates, results, duels): large enough for a burst."""

EVENT_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=EVENT_DEPTH,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.VOLATILE,
)
STATE_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=1,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.TRANSIENT_LOCAL,
)
STATUS_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=10,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.VOLATILE,
)


@dataclass(frozen=True)
class TopicSpec:
    """One topic of the exchange."""

    key: str
    name: str
    msg_type: type
    type_name: str
    qos: QoSProfile
    publisher: str
    subscribers: tuple[str, ...]
    schema: str
    meaning: str


CANDIDATE = TopicSpec(
    "candidate",
    "/localpbo/candidate",
    Float64MultiArray,
    "std_msgs/msg/Float64MultiArray",
    EVENT_QOS,
    "optimizer",
    ("simulator", "judge"),
    "CandidateMsg",
    "θ to evaluate, task units; ids in layout.dim[0].label",
)
EPISODE_RESULT = TopicSpec(
    "episode_result",
    "/localpbo/episode_result",
    DiagnosticStatus,
    "diagnostic_msgs/msg/DiagnosticStatus",
    EVENT_QOS,
    "simulator",
    ("oracle", "judge"),
    "EpisodeResult",
    "episode return (or failure) of one candidate",
)
DUEL_REQUEST = TopicSpec(
    "duel_request",
    "/localpbo/duel_request",
    DiagnosticStatus,
    "diagnostic_msgs/msg/DiagnosticStatus",
    EVENT_QOS,
    "optimizer",
    ("oracle", "judge"),
    "DuelRequest",
    "compare candidates first_id and second_id",
)
DUEL_OUTCOME = TopicSpec(
    "duel_outcome",
    "/localpbo/duel_outcome",
    DiagnosticStatus,
    "diagnostic_msgs/msg/DiagnosticStatus",
    EVENT_QOS,
    "oracle or judge",
    ("optimizer",),
    "DuelOutcome",
    "winner/loser, indifferent or failed for one duel",
)
INCUMBENT = TopicSpec(
    "incumbent",
    "/localpbo/incumbent",
    Float64MultiArray,
    "std_msgs/msg/Float64MultiArray",
    STATE_QOS,
    "optimizer",
    ("any",),
    "Incumbent",
    "current best θ (from preferences only), task units; latched",
)
RUN_CONFIG = TopicSpec(
    "run_config",
    "/localpbo/run_config",
    String,
    "std_msgs/msg/String",
    STATE_QOS,
    "optimizer",
    ("simulator", "oracle", "judge", "recorder"),
    "RunConfig",
    "JSON run configuration; latched",
)
STATUS = TopicSpec(
    "status",
    "/localpbo/status",
    DiagnosticArray,
    "diagnostic_msgs/msg/DiagnosticArray",
    STATUS_QOS,
    "every node",
    ("any",),
    "Status",
    "node state and drop counters",
)

SPECULATIVE_CANDIDATE = TopicSpec(
    "speculative_candidate",
    "/localpbo/speculative_candidate",
    Float64MultiArray,
    "std_msgs/msg/Float64MultiArray",
    EVENT_QOS,
    "optimizer (speculate)",
    ("simulator", "judge"),
    "CandidateMsg",
    "a candidate the next ask may propose (prepared branch); evaluated ahead, never recorded",
)
"""Not one of :data:`ALL_TOPICS`: work that may never be asked is not part of the run's
record. An evaluator may run its episode ahead and keep the result for the real candidate
message with the same id and θ (episodes are a function of run seed, id and θ)."""

ALL_TOPICS: tuple[TopicSpec, ...] = (
    CANDIDATE,
    EPISODE_RESULT,
    DUEL_REQUEST,
    DUEL_OUTCOME,
    INCUMBENT,
    RUN_CONFIG,
    STATUS,
)
TOPICS_BY_KEY: dict[str, TopicSpec] = {t.key: t for t in ALL_TOPICS}
TOPICS_BY_NAME: dict[str, TopicSpec] = {t.name: t for t in ALL_TOPICS}
