"""The ``localpbo`` command: ``bench``, ``demo``, ``sweep`` (:mod:`localpbo_core.sweep`) and
``report`` (:mod:`localpbo_core.report`) here; ``run``, ``replay`` and ``bag-info`` from the ROS
node package.

``bench`` drives one :class:`~localpbo_core.session.Session` per (algorithm, seed) in-process
and writes its outputs (:mod:`localpbo_core.bench`); ``demo`` is a short in-process comparison
on the small MuJoCo task (Swimmer, 16-D linear policy), TuRPBO against Sobol.

Nothing here imports ROS: the ROS subcommands' parsers are added from
``localpbo_ros.commands``, imported inside :func:`_add_ros_commands` (that module imports
rclpy only inside the chosen command). No module imports this one: what the CLI shares with
sweeps, specs, reports and the ROS commands lives below it (:mod:`localpbo_core.arguments`,
:mod:`localpbo_core.run_documents`, :mod:`localpbo_core.bench`).
"""

from __future__ import annotations

import argparse
import importlib.util
import sys
from collections.abc import Sequence
from pathlib import Path

from localpbo_core.arguments import (
    add_report_command,
    flag_of,
    json_object,
    parse_options,
    parse_seeds,
)
from localpbo_core.bench import bench, format_table, summarize
from localpbo_core.optimizers.registry import available_optimizers
from localpbo_core.presets import available_presets, expand
from localpbo_core.settings import (
    DEFAULT_INITIAL_DESIGN,
    DEFAULT_NOISE_FRACTION,
    DEFAULT_TIE_THRESHOLD,
    SettingError,
)

DEMO_PROBLEM = "swimmer"
DEMO_BUDGET = 40


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
        help=f"comma-separated algorithms; available: {', '.join(available_optimizers())}; "
        f"or presets (an algorithm with options, localpbo_core/presets.py): "
        f"{', '.join(available_presets())}",
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
    sweep.add_argument(
        "--time-limit",
        default=None,
        metavar="DURATION",
        help="e.g. 5400, 90m, 1h30m: start no run that its group's longest stored run says "
        "would end later, unless a checkpoint interval is left, and stop the runs still under "
        "way at the limit",
    )
    sweep.add_argument(
        "--times-from",
        action="append",
        metavar="DIR",
        help="for --time-limit, a group with no stored run here takes the longest of the same "
        "runs stored in DIR (repeatable)",
    )
    sweep.add_argument(
        "--checkpoint-every",
        default="10m",
        metavar="DURATION",
        help="write each run's state every DURATION of the run (default 10m), so that a "
        "stopped run continues from it in the next sweep",
    )
    sweep.add_argument(
        "--no-checkpoints",
        action="store_true",
        help="neither write nor continue checkpoints (a stopped run starts again)",
    )
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
    sweep.add_argument(
        "--rerun-changed",
        action="store_true",
        help="run again the stored runs whose algorithm's code changed since they were stored "
        "(or carry no known code version)",
    )
    sweep.add_argument("--dry-run", action="store_true", help="list the runs and their state")
    sweep.add_argument("--no-progress", action="store_true", help="hide the progress bar")
    add_report_command(sub)


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
            known = available_optimizers() + available_presets()
            for a in algorithms:
                if a not in known:
                    raise SettingError(
                        "algorithm", f"unknown algorithm {a!r}; available: {', '.join(known)}"
                    )
            if len(set(algorithms)) != len(algorithms):
                raise SettingError("algorithm", "repeated algorithm")
            runs = {a: expand(a, {})[0] for a in algorithms}
            if len(set(runs.values())) != len(runs):
                raise SettingError(
                    "algorithm",
                    f"{', '.join(f'{a} ({r})' for a, r in runs.items())}: two of them run the "
                    "same algorithm, and a bench names its runs by algorithm; bench them into "
                    "separate --out folders",
                )
            seeds = parse_seeds(args.seeds)
            problem = args.problem
            budget, initial_design, noise = args.budget, args.initial_design, args.noise
            per_alg = parse_options(args.option, algorithms)
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
