"""Ablation: what "can't tell" answers are worth to the model, and which threshold to use.

A simulated judge (:class:`~localpbo_core.problems.oracle.DuelOracle`, paper eqs. (2)-(3),
noise 10% of the value range) answers "can't tell" when its noisy difference is below
``--indifference`` times the value range (0.05: 17-27% of the duels). Variants, each on
the same seeds and therefore the same initial design and the same oracle noise per duel id:

* ``drop``: a "can't tell" answer closes its duel for the optimizer's own rules (it is in the
  history as :class:`~localpbo_core.optimizers.base.Indifferent`: the incumbent is kept, a
  trust region counts no success, exactly as in the tie variants) but the pairwise GP never
  sees it: the model is the paper's probit (``eps = 0``) on the decisive duels only. This is
  what a user gets by discarding "can't tell" answers. A GP cannot be fitted on no duel, so
  while every answer so far was a tie (the first duel or two of some seeds) those ties are
  fitted with ``eps = 0.5``; from the first decisive answer on they are dropped.
* ``eps=<e>``: the ordinal likelihood of :mod:`localpbo_core.surrogate.ordinal` with threshold
  ``e`` (latent units, sigma_n = 1) for ties *and* decisive duels.

Reported, mean +- sample std over seeds: the best true value seen at the end (``best_seen``,
paper Sec. 6's metric) and the true value of the final incumbent (what a run would deploy
from preferences alone); true values are read only by this report, never by the algorithms.
Each with a paired two-sided Wilcoxon signed-rank test of the ``eps`` variant against
``drop`` (same seeds), and the rate of "can't tell" answers.

The judge's threshold in latent units: with oracle noise std ``s = 0.1`` value ranges per value
and the probit's ``sigma_n = 1``, one latent unit is about ``s``, so ``--indifference 0.05``
corresponds to ``eps = 0.5`` if the GP's utility scale matched the noise exactly.

    python -m localpbo_core.benchmarks.tie_ablation [--seeds 0-9] [--eps 0.25,0.5,1.0]

A script, not a test: it prints figures and asserts nothing.
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Sequence

import numpy as np
import torch
from scipy.stats import wilcoxon

from localpbo_core.arguments import parse_seeds
from localpbo_core.loop import run_session
from localpbo_core.session import AnswerKind, RunSettings, Session

_EMPTY = np.empty((0, 2), dtype=np.int64)
BOOTSTRAP_EPS = 0.5
"""``eps`` of the ``drop`` variant's fits while no decisive answer exists yet."""


def drop_ties(session: Session) -> None:
    """Make ``session``'s model see decisive duels only, with ``eps = 0`` (module docstring).

    The optimizer keeps ``tie_threshold > 0`` so that it accepts the ties into its history;
    only its surrogate refitter (TuRPBO, qEUBO, and the local phase of PrefSQP and GIPBO(r))
    is switched to the paper's probit and handed no ties.
    """
    opt = session.optimizer
    refitter = opt._refitter  # type: ignore[attr-defined]
    all_ties = opt.ties

    def decisive_only() -> np.ndarray:
        if len(opt.comparisons()):
            refitter.tie_threshold = 0.0
            return _EMPTY
        refitter.tie_threshold = BOOTSTRAP_EPS
        return all_ties()

    opt.ties = decisive_only  # type: ignore[method-assign]


def run_variant(
    problem: str, algorithm: str, seed: int, budget: int, indifference: float, eps: float | None
) -> tuple[float, float, float]:
    """One run; ``eps=None`` is the ``drop`` variant. Returns ``(best_seen, true value of the
    final incumbent, tie rate)``."""
    settings = RunSettings(
        algorithm=algorithm,
        problem=problem,
        seed=seed,
        budget=budget,
        tie_threshold=BOOTSTRAP_EPS if eps is None else eps,
        indifference=indifference,
    )
    session = Session(settings)
    if eps is None:
        drop_ties(session)
    trace = run_session(session)
    ties = sum(a.kind is AnswerKind.INDIFFERENT for a in trace.answers)
    incumbent = session.optimizer.incumbent
    assert incumbent is not None
    final = float(session.problem.true_value(incumbent.theta))
    return float(trace.records[-1].best_seen), final, ties / max(len(trace.answers), 1)


def _p_value(x: np.ndarray, y: np.ndarray) -> str:
    diff = x - y
    return f"{wilcoxon(diff).pvalue:.3f}" if np.any(diff != 0) else "1.000"


def main(argv: Sequence[str] | None = None) -> int:
    """Run the ablation and print the table."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--problems", default="hartmann6:62,rosenbrock16:162", help="problem:budget,..."
    )
    parser.add_argument("--algorithms", default="turpbo,prefsqp,gipbor")
    parser.add_argument("--seeds", default="0-9")
    parser.add_argument("--eps", default="0.25,0.5,1.0")
    parser.add_argument("--indifference", type=float, default=0.05)
    args = parser.parse_args(argv)
    torch.set_num_threads(1)
    seeds = parse_seeds(args.seeds)
    eps_values = [float(e) for e in args.eps.split(",")]
    variants: list[tuple[str, float | None]] = [("drop", None)]
    variants += [(f"eps={e:g}", e) for e in eps_values]
    print(
        f"{'problem':<13} {'algorithm':<8} {'variant':<9} {'ties':>5} "
        f"{'best_seen mean ± std':>22} {'p':>6} {'incumbent mean ± std':>22} {'p':>6}"
    )
    t0 = time.perf_counter()
    for spec in args.problems.split(","):
        problem, _, budget = spec.partition(":")
        for algorithm in args.algorithms.split(","):
            best: dict[str, np.ndarray] = {}
            final: dict[str, np.ndarray] = {}
            for name, eps in variants:
                runs = [
                    run_variant(problem, algorithm, s, int(budget), args.indifference, eps)
                    for s in seeds
                ]
                best[name] = b = np.array([r[0] for r in runs])
                final[name] = f = np.array([r[1] for r in runs])
                rate = float(np.mean([r[2] for r in runs]))
                p_best = p_final = "-"
                if name != "drop":
                    p_best = _p_value(b, best["drop"])
                    p_final = _p_value(f, final["drop"])
                print(
                    f"{problem:<13} {algorithm:<8} {name:<9} {rate:>5.2f} "
                    f"{b.mean():>10.4g} ± {b.std(ddof=1):<9.3g} {p_best:>6} "
                    f"{f.mean():>10.4g} ± {f.std(ddof=1):<9.3g} {p_final:>6}",
                    flush=True,
                )
    print(
        f"total {time.perf_counter() - t0:.0f} s; seeds {args.seeds}, indifference "
        f"{args.indifference:g}",
        flush=True,
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
