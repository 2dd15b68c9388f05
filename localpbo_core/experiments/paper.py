"""The paper's compute times (App. E and the compute-time table of Sec. 6), in one place.

Optimizer seconds per run (mean over the paper's runs on 8-core CPU nodes), keyed by problem
and algorithm. "--" cells of the paper (HB-EI and GIPBO were not run beyond 32 dimensions) are
absent. Used by ``localpbo report`` and ``benchmarks/algorithms_compute.py``.
"""

from __future__ import annotations

PAPER_SECONDS: dict[str, dict[str, float]] = {
    "hartmann6": {
        "sobol": 0.023,
        "glisp": 9.0,
        "qeubo": 33.0,
        "hbei": 175.0,
        "gipbo": 245.0,
        "gipbor": 2.6,
        "turpbo": 46.0,
        "prefsqp": 22.0,
    },
    "rosenbrock16": {
        "sobol": 0.059,
        "glisp": 7.5,
        "qeubo": 171.0,
        "hbei": 716.0,
        "gipbo": 2453.0,
        "gipbor": 4.8,
        "turpbo": 143.0,
        "prefsqp": 66.0,
    },
    "levy32": {
        "sobol": 0.14,
        "glisp": 20.0,
        "qeubo": 707.0,
        "hbei": 7550.0,
        "gipbo": 15556.0,
        "gipbor": 12.0,
        "turpbo": 520.0,
        "prefsqp": 553.0,
    },
    "styblinskitang64": {
        "sobol": 0.29,
        "glisp": 94.0,
        "qeubo": 4921.0,
        "gipbor": 34.0,
        "turpbo": 3162.0,
        "prefsqp": 2918.0,
    },
    "hopper": {"turpbo": 489.0, "hbei": 7082.0},
}


def paper_seconds(problem: str, algorithm: str) -> float | None:
    """The paper's seconds per run of ``algorithm`` on ``problem``, or None if not reported."""
    return PAPER_SECONDS.get(problem, {}).get(algorithm)
