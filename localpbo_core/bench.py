"""``localpbo bench``'s work: every (algorithm, seed) run in-process
(:func:`localpbo_core.loop.run_session`) and its outputs: ``results.csv`` (one row per
evaluation, columns ``RESULT_COLUMNS``), ``summary.csv``, ``best_seen.png`` and one
``runs/*.json`` per run (:mod:`localpbo_core.run_documents`)."""

from __future__ import annotations

import csv
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from localpbo_core.loop import RESULT_COLUMNS, EvaluationRecord, run_session
from localpbo_core.run_documents import run_file_name, write_trace
from localpbo_core.settings import DEFAULT_INITIAL_DESIGN, DEFAULT_NOISE_FRACTION, RunSettings


def bench(
    problem_name: str,
    algorithms: Sequence[str],
    seeds: Sequence[int],
    out: Path,
    budget: int | None = None,
    initial_design: int = DEFAULT_INITIAL_DESIGN,
    noise: float = DEFAULT_NOISE_FRACTION,
    options: dict[str, dict[str, object]] | None = None,
    progress: bool = True,
    problem_options: dict[str, object] | None = None,
    tie_threshold: float = 0.0,
    indifference: float = 0.0,
) -> list[EvaluationRecord]:
    """Run every (algorithm, seed), write the outputs into ``out`` and return all records.

    Every configuration is validated (problem, algorithms, options, budget, noise) before
    any run starts.

    Raises:
        SettingError: naming the refused setting.
    """
    from tqdm import tqdm

    from localpbo_core.session import Session, build_problem

    options = options or {a: {} for a in algorithms}
    plans = [
        RunSettings(
            algorithm=alg,
            problem=problem_name,
            seed=seed,
            budget=budget,
            initial_design=initial_design,
            noise_fraction=noise,
            tie_threshold=tie_threshold,
            indifference=indifference,
            optimizer_options=options.get(alg, {}),
            problem_options=problem_options or {},
        )
        for alg in algorithms
        for seed in seeds
    ]
    problem = build_problem(plans[0])
    budgets = [Session(p, problem).budget for p in plans if p.seed == seeds[0]]  # fail at start
    out.mkdir(parents=True, exist_ok=True)
    (out / "runs").mkdir(exist_ok=True)
    records: list[EvaluationRecord] = []
    total = sum(budgets) * len(seeds)
    with tqdm(total=total, disable=not progress, unit="eval", dynamic_ncols=True) as bar:
        for plan in plans:
            bar.set_description(f"{plan.algorithm} seed {plan.seed}")
            trace = run_session(Session(plan, problem), on_evaluation=lambda _r: bar.update(1))
            records.extend(trace.records)
            write_trace(plan, trace, out / "runs" / run_file_name(plan))
            write_results(records, out / "results.csv")
    summary = summarize(records)
    write_summary(summary, out / "summary.csv")
    plot_best_seen(records, out / "best_seen.png")
    return records


def write_results(records: Sequence[EvaluationRecord], path: Path) -> None:
    """``results.csv``: one row per evaluation."""
    with path.open("w", newline="") as fh:
        writer = csv.writer(fh)
        writer.writerow(RESULT_COLUMNS)
        for r in records:
            writer.writerow(r.as_row())


def summarize(records: Sequence[EvaluationRecord]) -> list[dict[str, object]]:
    """Per algorithm: mean ± std over runs of final best-seen, final cumulative and the
    optimizer's total seconds per run (sum of ``decision_seconds``)."""
    runs: dict[tuple[str, int], list[EvaluationRecord]] = {}
    for r in records:
        runs.setdefault((r.algorithm, r.seed), []).append(r)
    rows = []
    for alg in dict.fromkeys(r.algorithm for r in records):
        finals = [v for (a, _), v in runs.items() if a == alg]
        best = np.array([v[-1].best_seen for v in finals])
        cum = np.array([v[-1].cumulative for v in finals])
        secs = np.array([sum(x.decision_seconds for x in v) for v in finals])
        rows.append(
            {
                "problem": finals[0][0].problem,
                "algorithm": alg,
                "runs": len(finals),
                "evaluations": len(finals[0]),
                "best_seen_mean": best.mean(),
                "best_seen_std": best.std(ddof=1) if len(best) > 1 else 0.0,
                "cumulative_mean": cum.mean(),
                "cumulative_std": cum.std(ddof=1) if len(cum) > 1 else 0.0,
                "optimizer_seconds_mean": secs.mean(),
                "optimizer_seconds_std": secs.std(ddof=1) if len(secs) > 1 else 0.0,
            }
        )
    return rows


def write_summary(rows: Sequence[dict[str, object]], path: Path) -> None:
    """``summary.csv``: the rows of :func:`summarize`."""
    with path.open("w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)


def format_table(rows: Sequence[dict[str, object]]) -> str:
    """The final table printed by ``bench``."""
    lines = [
        f"{'algorithm':<12} {'runs':>4} {'best_seen (mean ± std)':>26} "
        f"{'cumulative (mean ± std)':>28} {'optimizer s/run':>18}"
    ]
    for r in rows:
        lines.append(
            f"{r['algorithm']:<12} {r['runs']:>4} "
            f"{r['best_seen_mean']:>13.4g} ± {r['best_seen_std']:<10.3g} "
            f"{r['cumulative_mean']:>15.5g} ± {r['cumulative_std']:<10.4g} "
            f"{r['optimizer_seconds_mean']:>9.3g} ± {r['optimizer_seconds_std']:<6.2g}"
        )
    return "\n".join(lines)


def plot_best_seen(records: Sequence[EvaluationRecord], path: Path) -> None:
    """Mean ± std of best-seen and cumulative vs evaluation, one line per algorithm."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(11, 4))
    for alg in dict.fromkeys(r.algorithm for r in records):
        by_seed: dict[int, list[EvaluationRecord]] = {}
        for r in records:
            if r.algorithm == alg:
                by_seed.setdefault(r.seed, []).append(r)
        n = min(len(v) for v in by_seed.values())
        x = np.arange(1, n + 1)
        for ax, key in zip(axes, ("best_seen", "cumulative"), strict=True):
            y = np.array([[getattr(r, key) for r in v[:n]] for v in by_seed.values()])
            m, s = y.mean(0), y.std(0)
            ax.plot(x, m, label=alg)
            ax.fill_between(x, m - s, m + s, alpha=0.2)
    title = records[0].problem if records else ""
    for ax, key in zip(axes, ("best-seen f_true", "cumulative f_true"), strict=True):
        ax.set_xlabel("evaluation")
        ax.set_ylabel(key)
        ax.set_title(f"{title}: {key} (mean ± std over seeds)")
        ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
