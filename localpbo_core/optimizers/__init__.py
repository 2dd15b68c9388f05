"""Ask/tell preference optimizers (paper Sec. 5, App. C).

The ask/tell contract (:mod:`localpbo_core.optimizers.base`) and the registry load only numpy;
each algorithm module (and torch/BoTorch with it) is imported when first built.
"""

from typing import Any

from localpbo_core.optimizers.base import Ask, Candidate, Duel, Indifferent, Outcome
from localpbo_core.optimizers.preference_optimizer import (
    BudgetExhausted,
    History,
    InvalidOutcome,
    PendingDuels,
    PreferenceOptimizer,
)
from localpbo_core.optimizers.registry import (
    available_optimizers,
    make_optimizer,
    optimizer_defaults,
    optimizer_options,
    register_optimizer,
)

_LAZY = {
    "SobolOptimizer": "localpbo_core.optimizers.sobol",
    "TuRPBO": "localpbo_core.optimizers.turpbo",
}


def __getattr__(name: str) -> Any:
    """Algorithm classes, imported on first use."""
    if name in _LAZY:
        import importlib

        return getattr(importlib.import_module(_LAZY[name]), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


__all__ = [
    "Ask",
    "BudgetExhausted",
    "Candidate",
    "Duel",
    "History",
    "Indifferent",
    "InvalidOutcome",
    "Outcome",
    "PendingDuels",
    "PreferenceOptimizer",
    "SobolOptimizer",
    "TuRPBO",
    "available_optimizers",
    "make_optimizer",
    "optimizer_defaults",
    "optimizer_options",
    "register_optimizer",
]
