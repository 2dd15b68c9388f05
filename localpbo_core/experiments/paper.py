"""The paper's reported numbers, in one place: compute times and the policy-search table.

* :data:`PAPER_SECONDS`: optimizer seconds per run (mean over the paper's 10 runs on 8-core
  CPU nodes), keyed by problem key and algorithm: the compute-time table of Sec. 6
  (synthetic functions) and the per-run table of the computational-resources appendix (GP
  sample paths within / out of model, Hopper, Walker2d). GP keys are
  ``gp<d>_l<lengthscale>/within`` and ``.../out``, as :func:`problem_key` builds them from a
  stored run. "--" cells of the paper (HB-EI and GIPBO were not run beyond 32 dimensions)
  are absent. That appendix heads its local columns "TuRBO" and "BayeSQP": TuRPBO and
  PrefSQP.
* :data:`PAPER_POLICY_WARM_START`: the policy-search table with warm start (App. D.6):
  final best-seen and final cumulative, mean and std over 10 runs.

The paper gives its synthetic and GP results as figures only, so no numbers of theirs exist
to set beside ours there. Used by ``localpbo report`` and the compute benchmarks.
"""

from __future__ import annotations

PAPER_SEEDS = tuple(range(10))
"""The paper's runs per experiment (Sec. 6, its settings table: 10 runs): the seeds a group
needs to count as stored."""

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
    "hopper": {
        "sobol": 3.3,
        "glisp": 29.0,
        "qeubo": 1418.0,
        "hbei": 7082.0,
        "gipbo": 15894.0,
        "gipbor": 35.0,
        "turpbo": 489.0,
        "prefsqp": 351.0,
    },
    "walker2d": {
        "sobol": 11.0,
        "glisp": 287.0,
        "qeubo": 22652.0,
        "gipbor": 164.0,
        "turpbo": 17039.0,
        "prefsqp": 15262.0,
    },
}

_GP_ALGORITHMS = ("sobol", "glisp", "qeubo", "hbei", "gipbo", "gipbor", "turpbo", "prefsqp")
_GP_SECONDS: dict[str, tuple[float | None, ...]] = {
    # key: (sobol, glisp, qeubo, hbei, gipbo, gipbor, turpbo, prefsqp)
    "gp8_l0.1/within": (0.039, 15, 14, 107, 311, 1.3, 45, 6.7),
    "gp8_l0.5/within": (0.037, 6.0, 19, 287, 532, 1.1, 47, 12),
    "gp16_l0.1/within": (0.099, 12, 75, 626, 1794, 1.6, 101, 21),
    "gp16_l0.5/within": (0.097, 12, 96, 1206, 2900, 2.1, 103, 30),
    "gp32_l0.1/within": (0.42, 30, 341, 6294, 28955, 3.5, 345, 117),
    "gp32_l0.5/within": (0.39, 30, 193, 6852, 34879, 3.9, 252, 147),
    "gp64_l0.1/within": (0.49, 91, 13171, None, None, 12, 1564, 839),
    "gp64_l0.5/within": (0.49, 94, 1707, None, None, 17, 1195, 1583),
    "gp96_l0.1/within": (0.93, 227, 27048, None, None, 28, 5902, 3710),
    "gp96_l0.5/within": (1.7, 237, 11749, None, None, 45, 4142, 7727),
    "gp8_l0.1/out": (0.042, 10, 40, 304, 368, 3.1, 58, 23),
    "gp8_l0.5/out": (0.044, 8.4, 42, 285, 432, 2.9, 56, 22),
    "gp16_l0.1/out": (0.18, 13, 420, 1419, 1939, 10.0, 303, 309),
    "gp16_l0.5/out": (0.25, 11, 191, 1304, 1984, 4.0, 135, 61),
    "gp32_l0.1/out": (0.22, 29, 775, 6787, 13568, 7.0, 489, 310),
    "gp32_l0.5/out": (0.20, 30, 943, 7015, 14496, 8.1, 445, 264),
    "gp64_l0.1/out": (0.87, 87, 3210, None, None, 36, 2682, 2650),
    "gp64_l0.5/out": (1.0, 91, 3873, None, None, 49, 2683, 2422),
    "gp96_l0.1/out": (0.93, 243, 12120, None, None, 109, 11096, 12789),
    "gp96_l0.5/out": (0.78, 242, 16148, None, None, 100, 11050, 11315),
}
for _key, _row in _GP_SECONDS.items():
    PAPER_SECONDS[_key] = {
        a: float(v) for a, v in zip(_GP_ALGORITHMS, _row, strict=True) if v is not None
    }

PAPER_POLICY_WARM_START: dict[str, dict[str, tuple[tuple[float, float], tuple[float, float]]]] = {
    # problem: algorithm: ((final best-seen mean, std), (final cumulative mean, std))
    "hopper": {
        "sobol": ((360, 239), (4888, 519)),
        "glisp": ((630, 346), (17457, 7249)),
        "qeubo": ((629, 301), (7324, 2582)),
        "hbei": ((372, 246), (70445, 47721)),
        "prefsqp": ((427, 239), (81884, 76833)),
        "gipbor": ((453, 330), (82143, 59092)),
        "gipbo": ((489, 318), (90767, 66906)),
        "turpbo": ((768, 305), (91796, 53199)),
    },
    "walker2d": {
        "sobol": ((113, 39), (-6580, 237)),
        "glisp": ((112, 47), (-5921, 622)),
        "qeubo": ((122, 52), (-6975, 180)),
        "prefsqp": ((202, 83), (31895, 16962)),
        "gipbor": ((267, 131), (40389, 25571)),
        "turpbo": ((275, 109), (37517, 18229)),
    },
}
"""App. D.6, policy search with warm start (the paper's table; GIPBO and HB-EI not run on
Walker2d)."""


def problem_key(problem: str, options: dict[str, object], within_model: bool) -> str:
    """The key of a run's problem in :data:`PAPER_SECONDS`: the problem name, or for a GP
    sample path ``gp<d>_l<lengthscale>/within|out``."""
    if problem != "gp_sample":
        return problem
    dim, ls = options.get("dim"), options.get("lengthscale")
    return f"gp{dim}_l{float(str(ls)):g}/{'within' if within_model else 'out'}"


def paper_seconds(problem: str, algorithm: str) -> float | None:
    """The paper's seconds per run of ``algorithm`` on ``problem`` (a :func:`problem_key`),
    or None if not reported."""
    return PAPER_SECONDS.get(problem, {}).get(algorithm)
