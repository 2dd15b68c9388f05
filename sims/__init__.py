"""localpbo_sims: MuJoCo linear-policy tasks for local PBO (paper Sec. 6, App. D.6).

Imports only mujoco, gymnasium and numpy. Tasks satisfy ``localpbo_core``'s ``Problem``
protocol structurally (``name``, ``dim``, ``value_range``, ``to_native``, ``evaluate``,
``true_value``).
"""

from .ars import ArsPolicy, load_ars_policy
from .episode import (
    HOPPER_V5,
    INVERTED_PENDULUM_V5,
    SWIMMER_V5,
    WALKER2D_V5,
    EnvSpec,
    EpisodeResult,
    EpisodeRunner,
    Recording,
)
from .tasks import (
    MAX_MIN_VALUE_RANGES,
    TRUE_VALUE_SEEDS,
    VALUE_RANGES,
    LinearPolicyTask,
    TaskOptions,
    ThetaFromWeights,
    available_tasks,
    make_task,
    recorded_value_range,
)

__all__ = [
    "HOPPER_V5",
    "INVERTED_PENDULUM_V5",
    "MAX_MIN_VALUE_RANGES",
    "SWIMMER_V5",
    "TRUE_VALUE_SEEDS",
    "VALUE_RANGES",
    "WALKER2D_V5",
    "ArsPolicy",
    "EnvSpec",
    "EpisodeResult",
    "EpisodeRunner",
    "LinearPolicyTask",
    "Recording",
    "TaskOptions",
    "ThetaFromWeights",
    "available_tasks",
    "load_ars_policy",
    "make_task",
    "recorded_value_range",
]
