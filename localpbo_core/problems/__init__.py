"""Problems (maximised on [0,1]^d) and the noisy preference oracle (paper Sec. 2 and 6).

``make_problem(name, **options)`` builds synthetic BoTorch functions (``hartmann6``,
``rosenbrock16``, ``levy32``, ``styblinskitang64``) and, lazily from ``localpbo_sims``, the
MuJoCo linear-policy tasks (``hopper``, ``walker2d``, ``swimmer``).
"""

from .base import Problem
from .oracle import Duel, PreferenceOracle
from .registry import MUJOCO_PROBLEMS, available_problems, make_problem
from .synthetic import SYNTHETIC_PROBLEMS, SyntheticProblem

__all__ = [
    "MUJOCO_PROBLEMS",
    "SYNTHETIC_PROBLEMS",
    "Duel",
    "PreferenceOracle",
    "Problem",
    "SyntheticProblem",
    "available_problems",
    "make_problem",
]
