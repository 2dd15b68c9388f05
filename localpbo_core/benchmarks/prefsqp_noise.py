"""Ablation: why PrefSQP learns little under the paper's 10 % preference noise.

PrefSQP (paper Sec. 5.2, App. C.4) estimates the gradient and Hessian at its iterate from
``d`` duels against points in a ball of radius ``epsilon = 0.05`` and steps along the
Newton direction. With the oracle's noise at 10 % of the function's value range, the
utility differences inside such a ball are often far below the noise, so the duels carry
almost no information about the local slope — most of all on Hartmann 6, whose value is
near 0 on most of the cube, where the runs start.

The script runs PrefSQP variants on the same seeds and prints, per variant, the final
best-seen true value (mean ± std), the share of phases whose iterate did not move (the
Thompson line search chose ``eta = 0`` or the direction vanished), and the mean step
length:

* the paper's settings at noise 0 and 10 %;
* the local radius ``epsilon`` 0.1 and 0.2 (more signal per duel);
* the line searches of App. D.7 (``full`` step, ``eubo``) and BayeSQP's uncertainty-aware
  subproblem (``ev``);
* for reference, GIPBO, GIPBOr and TuRPBO at 10 %.

Run: ``python -m localpbo_core.benchmarks.prefsqp_noise [--problems hartmann6,rosenbrock16]
[--seeds 10]``. Asserts nothing.
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Mapping
from typing import Any

import numpy as np

from localpbo_core.loop import run_session
from localpbo_core.session import Session
from localpbo_core.settings import RunSettings
from localpbo_core.threads import use_fast_threads

VARIANTS: tuple[tuple[str, str, float, Mapping[str, Any]], ...] = (
    ("prefsqp, noise 0", "prefsqp", 0.0, {}),
    ("prefsqp (paper)", "prefsqp", 0.1, {}),
    ("prefsqp eps 0.1", "prefsqp", 0.1, {"epsilon": 0.1}),
    ("prefsqp eps 0.2", "prefsqp", 0.1, {"epsilon": 0.2}),
    ("prefsqp full step", "prefsqp", 0.1, {"line_search": "full"}),
    ("prefsqp eubo", "prefsqp", 0.1, {"line_search": "eubo"}),
    ("prefsqp ev", "prefsqp", 0.1, {"subproblem": "ev"}),
    ("gipbo", "gipbo", 0.1, {}),
    ("gipbor", "gipbor", 0.1, {}),
    ("turpbo", "turpbo", 0.1, {}),
)


def run_variant(
    problem: str, algorithm: str, noise: float, options: Mapping[str, Any], seeds: int
) -> dict[str, float]:
    """Final best-seen values and PrefSQP step statistics over ``seeds`` seeds."""
    best, still, steps = [], [], []
    for seed in range(seeds):
        settings = RunSettings(
            algorithm=algorithm,
            problem=problem,
            seed=seed,
            noise_fraction=noise,
            optimizer_options=dict(options),
        )
        session = Session(settings)
        best.append(run_session(session).records[-1].best_seen)
        centers = getattr(session.optimizer, "centers", None)
        if algorithm == "prefsqp" and centers is not None and len(centers) > 1:
            moves = np.linalg.norm(np.diff(np.asarray(centers), axis=0), axis=1)
            still.append(float(np.mean(moves < 1e-9)))
            steps.append(float(np.mean(moves)))
    return {
        "mean": float(np.mean(best)),
        "std": float(np.std(best, ddof=1)) if len(best) > 1 else 0.0,
        "still": float(np.mean(still)) if still else float("nan"),
        "step": float(np.mean(steps)) if steps else float("nan"),
    }


def main(argv: list[str] | None = None) -> None:
    """Print the ablation table."""
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--problems", default="hartmann6,rosenbrock16")
    parser.add_argument("--seeds", type=int, default=10)
    args = parser.parse_args(argv)
    use_fast_threads()
    for problem in args.problems.split(","):
        t0 = time.perf_counter()
        print(f"\n{problem}, seeds 0-{args.seeds - 1}, budget 2 + 10 d")
        print(
            f"{'variant':<20}{'noise':>6}  {'final best-seen':>22}{'iterate still':>15}{'step':>7}"
        )
        for label, algorithm, noise, options in VARIANTS:
            r = run_variant(problem, algorithm, noise, options, args.seeds)
            still = "" if np.isnan(r["still"]) else f"{100 * r['still']:.0f} %"
            step = "" if np.isnan(r["step"]) else f"{r['step']:.3f}"
            print(
                f"{label:<20}{noise:>6.2f}  {r['mean']:>12.4g} ± {r['std']:<8.3g}"
                f"{still:>15}{step:>7}",
                flush=True,
            )
        print(f"({time.perf_counter() - t0:.0f} s)")


if __name__ == "__main__":
    main()
