"""The ``localpbo`` command: ``bench``, ``demo``, ``sweep`` (:mod:`localpbo_core.sweep`) and
``report`` (:mod:`localpbo_core.report`) here; ``run``, ``replay`` and ``bag-info`` from the ROS
node package.

``bench`` drives one :class:`~localpbo_core.session.Session` per (algorithm, seed) in-process
(:func:`localpbo_core.loop.run_session`) and writes ``results.csv`` (one row per evaluation,
columns ``RESULT_COLUMNS``), ``summary.csv``, ``best_seen.png`` and one ``runs/*.json`` per run
(the candidates, values and answers it exchanged); ``demo`` is a short in-process comparison
on the small MuJoCo task (Swimmer, 16-D linear policy), TuRPBO against Sobol.

Nothing here imports ROS: the ROS subcommands' parsers are added from
``localpbo_ros.commands``, whose module imports rclpy only inside the chosen command.
"""

from __future__ import annotations

import argparse
import ast
import csv
import importlib.util
import json
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from localpbo_core.loop import RESULT_COLUMNS, EvaluationRecord, RunTrace, run_session
from localpbo_core.optimizers.registry import available_optimizers, optimizer_options
from localpbo_core.settings import (
    DEFAULT_INITIAL_DESIGN,
    DEFAULT_NOISE_FRACTION,
    DEFAULT_TIE_THRESHOLD,
    RunSettings,
    SettingError,
)

DEMO_PROBLEM = "swimmer"
DEMO_BUDGET = 40

FLAGS = {
    "problem": "--problem",
    "algorithm": "--algorithm",
    "seed": "--seeds",
    "budget": "--budget",
    "initial_design": "--initial-design",
    "noise_fraction": "--noise",
    "tie_threshold": "--tie-threshold",
    "indifference": "--indifference",
    "optimizer_options": "--option",
    "problem_options": "--problem",
}
"""The command-line flag of each run setting (for error messages)."""


def flag_of(field: str) -> str:
    """The flag that sets ``field`` (a :class:`SettingError` field), e.g. ``--option``."""
    head, _, rest = field.partition(".")
    flag = FLAGS.get(head, head)
    return f"{flag} {rest}" if rest else flag


def parse_seeds(text: str) -> list[int]:
    """Seeds from ``"0,1,2"``, ``"0-4"`` or a mix (``"0-2,7"``); all must be >= 0."""
    seeds: list[int] = []
    for part in text.split(","):
        part = part.strip()
        if not part:
            continue
        if "-" in part[1:]:
            lo, hi = part.split("-", 1)
            seeds.extend(range(int(lo), int(hi) + 1))
        else:
            seeds.append(int(part))
    if not seeds or any(s < 0 for s in seeds):
        raise ValueError("--seeds: expected non-negative integers such as 0,1,2 or 0-4")
    if len(set(seeds)) != len(seeds):
        raise ValueError("--seeds: repeated seed")
    return seeds


def _parse_value(text: str) -> object:
    try:
        return ast.literal_eval(text)
    except (ValueError, SyntaxError):
        return text


def _parse_options(items: Sequence[str], algorithms: Sequence[str]) -> dict[str, dict[str, object]]:
    """``key=value`` (every algorithm that accepts ``key``) or ``alg.key=value``."""
    per_alg: dict[str, dict[str, object]] = {a: {} for a in algorithms}
    for item in items:
        if "=" not in item:
            raise ValueError(f"--option: expected key=value, got {item!r}")
        key, value = item.split("=", 1)
        key = key.strip()
        parsed = _parse_value(value.strip())
        targets = list(algorithms)
        if "." in key:
            alg, key = key.split(".", 1)
            if alg not in algorithms:
                raise ValueError(f"--option {item!r}: algorithm {alg!r} is not in --algorithm")
            targets = [alg]
        accepted = [a for a in targets if key in optimizer_options(a)]
        if not accepted:
            raise ValueError(f"--option {key!r}: not an option of {', '.join(targets)}")
        for a in accepted:
            per_alg[a][key] = parsed
    return per_alg


def json_object(text: str) -> dict[str, object]:
    """An argparse type: a JSON object given on the command line."""
    try:
        value = json.loads(text)
    except json.JSONDecodeError as exc:
        raise argparse.ArgumentTypeError(f"not JSON: {exc}") from None
    if not isinstance(value, dict):
        raise argparse.ArgumentTypeError("must be a JSON object, e.g. '{\"episode_steps\": 200}'")
    return value


def _build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="localpbo",
        description="Local preferential Bayesian optimization: ROS 2 runs, replay, benchmarks.",
    )
    sub = parser.add_subparsers(dest="command", required=True)
    bench = sub.add_parser(
        "bench",
        help="run algorithms on a problem with a noisy preference oracle",
        description=(
            "Run the in-process loop (optimizer -> evaluation -> noisy duel) for every "
            "algorithm and seed. Writes OUT/results.csv (one row per evaluation), "
            "OUT/summary.csv and OUT/best_seen.png, and prints a final table."
        ),
    )
    bench.add_argument("--problem", required=True, help="problem name, e.g. hartmann6, hopper")
    bench.add_argument(
        "--algorithm",
        required=True,
        help=f"comma-separated algorithms; available: {', '.join(available_optimizers())}",
    )
    bench.add_argument(
        "--seeds", default="0", help="comma-separated run seeds or ranges, e.g. 0,1,2 or 0-4"
    )
    bench.add_argument(
        "--budget",
        type=int,
        default=None,
        help="evaluations per run, initial design included (default: initial design + 10 d; "
        "62 on Hartmann 6 = 2 + 10 d, paper App. D.1)",
    )
    bench.add_argument("--out", required=True, help="output directory (created if needed)")
    bench.add_argument(
        "--initial-design",
        type=int,
        default=DEFAULT_INITIAL_DESIGN,
        help="shared random initial points per run (paper: 2; policy search 5 d)",
    )
    bench.add_argument(
        "--noise",
        type=float,
        default=DEFAULT_NOISE_FRACTION,
        help="oracle noise std as a fraction of the problem's value range (paper: 0.1)",
    )
    bench.add_argument(
        "--tie-threshold",
        type=float,
        nargs="?",
        default=0.0,
        const=DEFAULT_TIE_THRESHOLD,
        metavar="EPS",
        help="indifference threshold eps of the ordinal likelihood: 'can't tell' answers are "
        f"used iff > 0 (default 0, the paper's model; the flag alone: {DEFAULT_TIE_THRESHOLD}, "
        "the value for a person judging)",
    )
    bench.add_argument(
        "--indifference",
        type=float,
        default=0.0,
        help="the simulated oracle answers 'can't tell' when its noisy difference is below "
        "this fraction of the value range (needs --tie-threshold > 0; default 0)",
    )
    bench.add_argument(
        "--batch-size", type=int, default=None, help="candidates per iteration q (default 1)"
    )
    bench.add_argument(
        "--option",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="algorithm option, repeatable; KEY=VALUE goes to every listed algorithm that "
        "accepts KEY, ALG.KEY=VALUE to one (e.g. turpbo.acquisition=qeubo)",
    )
    bench.add_argument(
        "--problem-options",
        type=json_object,
        default={},
        metavar="JSON",
        help="problem options as a JSON object, e.g. '{\"episode_steps\": 200}'",
    )
    bench.add_argument("--no-progress", action="store_true", help="hide the progress bar")
    for sp in (bench,):
        _add_threads(sp)
    demo = sub.add_parser(
        "demo",
        help="short real tuning run (TuRPBO vs Sobol on the Swimmer linear policy)",
        description=(
            f"TuRPBO against Sobol on the {DEMO_PROBLEM} linear-policy task (16-D), one seed, "
            f"{DEMO_BUDGET} evaluations each, 10%% oracle noise; about two minutes."
        ),
    )
    demo.add_argument("--out", default="localpbo_demo", help="output directory")
    demo.add_argument("--seed", type=int, default=0, help="run seed")
    _add_threads(demo)
    _add_sweep_commands(sub)
    _add_ros_commands(sub)
    return parser


def _add_sweep_commands(sub: argparse._SubParsersAction) -> None:
    """``sweep`` (:mod:`localpbo_core.sweep`) and ``report`` (:mod:`localpbo_core.report`)."""
    sweep = sub.add_parser(
        "sweep",
        help="run an experiment spec (problems x algorithms x seeds) on Ray, resumable",
        description=(
            "Run every run of SPEC (a YAML file or the name of a bundled spec, e.g. synthetic, "
            "gp_within, tiny) as a Ray task and store each finished run as "
            "OUT/runs/<run_id>.json.gz; runs already stored are skipped, so an interrupted "
            "sweep continues where it stopped."
        ),
    )
    sweep.add_argument("spec", help="spec file or bundled spec name")
    sweep.add_argument("--out", required=True, help="output folder (created if needed)")
    sweep.add_argument("--address", default=None, help="existing Ray cluster (default: local)")
    sweep.add_argument(
        "--workers", type=int, default=None, help="CPUs of the local Ray (default: all cores)"
    )
    sweep.add_argument(
        "--in-process", action="store_true", help="run sequentially in this process, no Ray"
    )
    sweep.add_argument("--max-runs", type=int, default=None, help="run at most N unfinished runs")
    sweep.add_argument("--problems", default=None, help="comma-separated problem labels")
    sweep.add_argument("--algorithms", default=None, help="comma-separated algorithm labels")
    sweep.add_argument("--variants", default=None, help="comma-separated variant labels")
    sweep.add_argument("--seeds", default=None, help="seeds or ranges, e.g. 0-4")
    sweep.add_argument(
        "--reuse",
        action="append",
        metavar="DIR",
        help="copy runs that the sweep in DIR stored with the same settings, options at "
        "their defaults included (repeatable)",
    )
    sweep.add_argument("--dry-run", action="store_true", help="list the runs and their state")
    sweep.add_argument("--no-progress", action="store_true", help="hide the progress bar")
    report = sub.add_parser(
        "report",
        help="figures and tables (with paired Wilcoxon tests) from stored runs",
        description=(
            "Read stored runs (sweep or bench output folders, or run files) and write "
            "Markdown tables and PNG figures into OUT (byte-identical on the same input)."
        ),
    )
    report.add_argument("results", nargs="+", help="result folders or run files")
    report.add_argument("--out", required=True, help="output folder (created if needed)")
    report.add_argument(
        "--alpha", type=float, default=0.05, help="significance level after Holm (default 0.05)"
    )
    report.add_argument("--name", default="report.md", help="report file name in OUT")
    report.add_argument(
        "--figures", default=".", help="folder for the PNGs, relative to OUT (default OUT)"
    )
    report.add_argument("--notes", default=None, help="Markdown file appended to the report")
    report.add_argument("--title", default="localpbo report", help="the report's heading")


def _add_ros_commands(sub: argparse._SubParsersAction) -> None:
    """Add ``run``, ``replay`` and ``bag-info``, contributed by the ROS node package.

    They live with the nodes (``localpbo_ros.commands``, which imports rclpy only when a
    command runs); without the ROS package installed the ``localpbo`` command lacks them.
    """
    if importlib.util.find_spec("localpbo_ros") is None:
        return
    from localpbo_ros.commands import add_subcommands

    add_subcommands(sub)


def _add_threads(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--torch-threads",
        type=int,
        default=None,
        help="torch and BLAS threads (default: 1 unless OMP_NUM_THREADS, MKL_NUM_THREADS or "
        "OPENBLAS_NUM_THREADS is set; one thread is fastest for the surrogate's small matrices)",
    )


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


def run_file_name(settings: RunSettings) -> str:
    """``<problem>_<algorithm>_seed<seed>.json``: one file per finished run."""
    return f"{settings.problem}_{settings.algorithm}_seed{settings.seed}.json"


def trace_document(settings: RunSettings, trace: RunTrace) -> dict[str, Any]:
    """One run as a JSON-ready document (schema ``localpbo/run/v1``): its settings, every
    candidate (native units and value), every accepted answer and every evaluation record."""
    return {
        "schema": "localpbo/run/v1",
        "settings": settings_document(settings),
        "candidates": [
            {"id": cid, "native": list(trace.native[cid]), "value": trace.values[cid]}
            for cid in sorted(trace.native)
        ],
        "answers": [
            {
                "duel_id": a.duel_id,
                "first": a.first,
                "second": a.second,
                "kind": a.kind.value,
                "winner": a.winner,
            }
            for a in trace.answers
        ],
        "records": [dict(zip(RESULT_COLUMNS, r.as_row(), strict=True)) for r in trace.records],
    }


def settings_document(settings: RunSettings) -> dict[str, Any]:
    """The fields of ``settings`` as stored with a run (JSON types: tuples become lists).
    ``tie_threshold`` and ``indifference`` appear only when > 0, so documents of runs without
    "can't tell" answers are unchanged."""
    doc: dict[str, Any] = {
        "algorithm": settings.algorithm,
        "problem": settings.problem,
        "seed": settings.seed,
        "budget": settings.budget,
        "initial_design": settings.initial_design,
        "noise_fraction": settings.noise_fraction,
        "optimizer_options": dict(settings.optimizer_options),
        "problem_options": dict(settings.problem_options),
    }
    if settings.tie_threshold > 0 or settings.indifference > 0:
        doc["tie_threshold"] = settings.tie_threshold
        doc["indifference"] = settings.indifference
    return dict(json.loads(json.dumps(doc, default=str)))


def write_trace(settings: RunSettings, trace: RunTrace, path: Path) -> None:
    """One run as JSON (:func:`trace_document`). Floats are written exactly (JSON's
    shortest round-trip representation)."""
    path.write_text(json.dumps(trace_document(settings, trace), default=str) + "\n")


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


def main(argv: Sequence[str] | None = None) -> int:
    """The ``localpbo`` command (its console script, :mod:`localpbo_core.console`, installs the
    stop guard first)."""
    from localpbo_core.stopping import release_start_guard
    from localpbo_core.threads import use_fast_threads

    parser = _build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "handles_signals", False):  # ``run`` stops cleanly on its own
        release_start_guard()
    if getattr(args, "torch_threads", None) is None:
        use_fast_threads()
    if hasattr(args, "func"):  # a command contributed by the ROS package
        return int(args.func(args))
    if args.command in ("sweep", "report"):
        try:
            if args.command == "sweep":
                from localpbo_core.sweep import main_sweep

                return main_sweep(args)
            from localpbo_core.report import main_report

            return main_report(args)
        except SettingError as exc:
            parser.exit(2, f"localpbo: error: {exc.field}: {exc.reason}\n")
        except ValueError as exc:
            parser.exit(2, f"localpbo: error: {exc}\n")
    try:
        if args.torch_threads is not None:
            if args.torch_threads < 1:
                raise SettingError("--torch-threads", f"must be >= 1, got {args.torch_threads}")
            import torch

            torch.set_num_threads(args.torch_threads)
        if args.command == "demo":
            problem, algorithms, seeds = DEMO_PROBLEM, ["turpbo", "sobol"], [args.seed]
            budget, initial_design, noise = DEMO_BUDGET, DEFAULT_INITIAL_DESIGN, None
            per_alg: dict[str, dict[str, object]] = {a: {} for a in algorithms}
            progress = True
        else:
            algorithms = [a.strip().lower() for a in args.algorithm.split(",") if a.strip()]
            if not algorithms:
                raise SettingError("algorithm", "empty")
            for a in algorithms:
                if a not in available_optimizers():
                    raise SettingError(
                        "algorithm",
                        f"unknown algorithm {a!r}; available: {', '.join(available_optimizers())}",
                    )
            if len(set(algorithms)) != len(algorithms):
                raise SettingError("algorithm", "repeated algorithm")
            seeds = parse_seeds(args.seeds)
            problem = args.problem
            budget, initial_design, noise = args.budget, args.initial_design, args.noise
            per_alg = _parse_options(args.option, algorithms)
            if args.batch_size is not None:
                for a in algorithms:
                    per_alg[a]["batch_size"] = args.batch_size
            progress = not args.no_progress
        out = Path(args.out)
        records = bench(
            problem,
            algorithms,
            seeds,
            out,
            budget=budget,
            initial_design=initial_design,
            noise=DEFAULT_NOISE_FRACTION if noise is None else noise,
            options=per_alg,
            progress=progress,
            problem_options=getattr(args, "problem_options", {}),
            tie_threshold=getattr(args, "tie_threshold", 0.0),
            indifference=getattr(args, "indifference", 0.0),
        )
    except SettingError as exc:
        parser.exit(2, f"localpbo: error: {flag_of(exc.field)}: {exc.reason}\n")
    except ValueError as exc:
        parser.exit(2, f"localpbo: error: {exc}\n")
    print(format_table(summarize(records)))
    print(f"results: {out / 'results.csv'}")
    print(f"summary: {out / 'summary.csv'}")
    print(f"plot:    {out / 'best_seen.png'}")
    print(f"runs:    {out / 'runs'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
