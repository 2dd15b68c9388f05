"""localpbo core: the math of local preferential Bayesian optimization (no ROS here).

Reference (cited as "the paper" throughout the code, by section and equation number):

    Johanna Menn, Miriam Kober, Paul Brunzema, David Stenger, Sebastian Trimpe.
    *Local Preferential Bayesian Optimization*. Preprint, 2026.

Its sections: 2 Problem Formulation (eqs. 1-3: the problem, the observation noise, the
preference); 4 Preference Modeling with Pairwise Gaussian Processes (eqs. 4-12: likelihood,
the matrix C, the joint predictive of values and derivatives, the covariance blocks);
5 Local Search Mechanisms (5.1 GIPBO, eqs. 13-17; 5.2 PrefSQP, eqs. 18-20; 5.3 TuRPBO);
6 Results; appendices B (proof of the approximation lemma), C Implementation Details
(C.2 GIPBO, C.3 GIPBOr, C.4 PrefSQP, C.5 TuRPBO), D Experimental Details (D.1 shared set-up,
D.2 pairwise-GP settings, D.3 algorithm configurations, D.4 GP sample paths, D.5 benchmark
functions, D.6 policy search, D.7 ablations) and E Computational Resources.
"""

from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from localpbo_core.optimizers import (
        Ask,
        Candidate,
        Duel,
        Indifferent,
        InvalidOutcome,
        Outcome,
        available_optimizers,
        make_optimizer,
    )

__all__ = [
    "Ask",
    "Candidate",
    "Duel",
    "Indifferent",
    "InvalidOutcome",
    "Outcome",
    "available_optimizers",
    "make_optimizer",
]


def __getattr__(name: str) -> Any:
    """The optimizer API, imported on first use: importing a submodule (e.g. the stop guard
    every executable loads first, ``localpbo_core.stopping``) loads no numpy."""
    if name in __all__:
        from localpbo_core import optimizers

        return getattr(optimizers, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
