"""Optimizer-only compute per run for every algorithm, next to the paper's App. E table.

For each problem (default Hartmann 6D, 62 evaluations, and Rosenbrock 16D, 162 evaluations:
the ``2 + 10d`` budget of App. D.1 with 2 initial points and 10 % oracle noise) and every
registered algorithm, one in-process run per seed (:func:`localpbo_core.loop.run_session`). The
optimizer's compute is the sum of ``decision_seconds`` (its own ``ask``/``tell`` time;
evaluations and the oracle excluded). Printed: seconds per run (mean over seeds), the paper's
figure (App. E, 8-core CPU nodes), the ratio paper/ours, the issue-5 target and the final
best-seen value (mean over seeds); also the process CPU time of the run ("cpu s/run"), which
stays meaningful when other processes load the machine (then the wall-clock figure grows).
``--tail K`` adds the mean optimizer seconds per decision over the last ``K`` evaluations of
each run ("last-K s/dec": the cost at the end of a run, where the models are largest), e.g.
for HB-EI on Levy 32 (322 evaluations; App. E gives only the per-run total, whose mean per
decision is printed beside it as "paper s/dec"). Before the timed runs each algorithm does
one untimed warm-up run of 4 evaluations (one-off costs of a process: lazy imports, numba
compilation in glis). Run single-threaded for comparable figures:

    python -m localpbo_core.benchmarks.algorithms_compute \\
        [--problems hartmann6,rosenbrock16] [--algorithms qeubo,glisp] [--seeds 0] \\
        [--option qeubo.hyperparameter_refit_every=5] [--tail 10] [--budget N]
"""

from __future__ import annotations

import argparse
import ast
import sys
import time
from collections.abc import Sequence

import numpy as np

from localpbo_core.experiments.paper import paper_seconds

#: Targets: minimum ratio paper/ours (GIPBOr: at most the paper's figure).
TARGET_RATIO: dict[str, float] = {
    "gipbo": 20.0,
    "prefsqp": 10.0,
    "qeubo": 10.0,
    "turpbo": 10.0,
    "gipbor": 1.0,
    "hbei": 10.0,
}


def run_one(
    problem_name: str,
    algorithm: str,
    seed: int,
    noise: float,
    options: dict[str, object] | None = None,
    budget: int | None = None,
    tail: int = 0,
) -> tuple[float, float, float, float]:
    """One run; returns (optimizer seconds, process CPU seconds of the run, final best-seen
    true value, mean optimizer seconds per evaluation over the last ``tail`` evaluations, NaN
    for ``tail = 0``). The CPU time includes the (negligible) synthetic evaluations and oracle;
    it is insensitive to other processes competing for the cores, unlike the wall-clock
    ``decision_seconds``."""
    from localpbo_core.loop import run_session
    from localpbo_core.session import RunSettings, Session

    settings = RunSettings(
        algorithm=algorithm,
        problem=problem_name,
        seed=seed,
        budget=budget,
        noise_fraction=noise,
        optimizer_options=options or {},
    )
    session = Session(settings)
    cpu0 = time.process_time()
    records = run_session(session).records
    cpu = time.process_time() - cpu0
    last = records[-tail:] if tail > 0 else []
    return (
        float(sum(r.decision_seconds for r in records)),
        cpu,
        float(records[-1].best_seen),
        float(np.mean([r.decision_seconds for r in last])) if last else float("nan"),
    )


def budget_of(problem_name: str, budget: int | None) -> int:
    """The run's evaluations: ``budget`` or the default ``2 + 10 d`` of App. D.1."""
    if budget is not None:
        return budget
    from localpbo_core.problems import make_problem
    from localpbo_core.settings import default_budget

    return default_budget(make_problem(problem_name).dim)


def _options(items: Sequence[str]) -> dict[str, dict[str, object]]:
    """``alg.key=value`` items -> ``{alg: {key: value}}`` (values as Python literals)."""
    out: dict[str, dict[str, object]] = {}
    for item in items:
        head, sep, value = item.partition("=")
        alg, dot, key = head.partition(".")
        if not sep or not dot or not key:
            raise ValueError(f"--option: expected alg.key=value, got {item!r}")
        try:
            parsed: object = ast.literal_eval(value)
        except (ValueError, SyntaxError):
            parsed = value
        out.setdefault(alg.strip().lower(), {})[key.strip()] = parsed
    return out


def _csv(text: str) -> list[str]:
    return [t.strip().lower() for t in text.split(",") if t.strip()]


def main(argv: Sequence[str] | None = None) -> int:
    """Run the benchmark and print the table."""
    from localpbo_core.optimizers import available_optimizers

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--problems", default="hartmann6,rosenbrock16")
    parser.add_argument("--algorithms", default=",".join(available_optimizers()))
    parser.add_argument("--seeds", default="0", help="comma-separated seeds")
    parser.add_argument("--noise", type=float, default=0.1, help="oracle noise fraction")
    parser.add_argument("--torch-threads", type=int, default=None, help="torch threads")
    parser.add_argument("--option", action="append", default=[], help="alg.key=value (repeatable)")
    parser.add_argument(
        "--tail", type=int, default=0, help="also print seconds per decision of the last K"
    )
    parser.add_argument("--budget", type=int, default=None, help="evaluations (default 2 + 10d)")
    args = parser.parse_args(argv)
    problems, algorithms = _csv(args.problems), _csv(args.algorithms)
    seeds = [int(s) for s in _csv(args.seeds)]
    options = _options(args.option)
    unknown = [a for a in algorithms if a not in available_optimizers()]
    if unknown:
        parser.error(f"--algorithms: unknown {unknown}; available {available_optimizers()}")
    if args.torch_threads is not None:
        import torch

        torch.set_num_threads(args.torch_threads)

    header = (
        f"{'problem':<14}{'algorithm':<10}{'ours s/run':>12}{'cpu s/run':>11}{'paper s':>10}"
        f"{'paper/ours':>12}{'target':>10}{'met':>5}{'best_seen':>12}"
    )
    if args.tail > 0:
        header += f"{f'last-{args.tail} s/dec':>16}{'paper s/dec':>13}"
    print(header)
    print("-" * len(header))
    for prob in problems:
        for alg in algorithms:
            # Untimed warm-up (lazy imports, numba JIT of glis): 2 decisions after the design.
            run_one(prob, alg, seeds[0], args.noise, options.get(alg), budget=4)
            runs = [
                run_one(prob, alg, s, args.noise, options.get(alg), args.budget, args.tail)
                for s in seeds
            ]
            secs = float(np.mean([r[0] for r in runs]))
            cpu = float(np.mean([r[1] for r in runs]))
            best = float(np.mean([r[2] for r in runs]))
            paper = paper_seconds(prob, alg)
            ratio = paper / secs if paper is not None and secs > 0 else None
            target = TARGET_RATIO.get(alg)
            met = "" if target is None or ratio is None else ("yes" if ratio >= target else "NO")
            print(
                f"{prob:<14}{alg:<10}{secs:>12.3f}{cpu:>11.3f}"
                f"{'-' if paper is None else f'{paper:g}':>10}"
                f"{'-' if ratio is None else f'{ratio:.1f}x':>12}"
                f"{'-' if target is None else f'>={target:g}x':>10}{met:>5}{best:>12.4g}",
                end="",
            )
            if args.tail > 0:
                tail = float(np.mean([r[3] for r in runs]))
                # the paper's per-run total over its decisions (one per evaluation after the
                # first two): its mean time per decision
                n_dec = max(budget_of(prob, args.budget) - 2, 1)
                per = "-" if paper is None else f"{paper / n_dec:.3g}"
                print(f"{tail:>16.3f}{per:>13}", end="")
            print(flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
