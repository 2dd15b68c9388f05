"""localpbo core: the math of local preferential Bayesian optimization (no ROS here)."""

from localpbo_core.optimizers import (
    Ask,
    Candidate,
    Duel,
    InvalidOutcome,
    Outcome,
    available_optimizers,
    make_optimizer,
)

__all__ = [
    "Ask",
    "Candidate",
    "Duel",
    "InvalidOutcome",
    "Outcome",
    "available_optimizers",
    "make_optimizer",
]
