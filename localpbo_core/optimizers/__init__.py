"""Ask/tell preference optimizers (DESIGN.md §3; paper Sec. 5, App. C)."""

from localpbo_core.optimizers.base import Ask, Candidate, Duel, Outcome
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
    optimizer_options,
    register_optimizer,
)
from localpbo_core.optimizers.sobol import SobolOptimizer
from localpbo_core.optimizers.turpbo import TuRPBO

__all__ = [
    "Ask",
    "BudgetExhausted",
    "Candidate",
    "Duel",
    "History",
    "InvalidOutcome",
    "Outcome",
    "PendingDuels",
    "PreferenceOptimizer",
    "SobolOptimizer",
    "TuRPBO",
    "available_optimizers",
    "make_optimizer",
    "optimizer_options",
    "register_optimizer",
]
