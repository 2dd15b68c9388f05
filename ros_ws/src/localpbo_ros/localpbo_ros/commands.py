"""``localpbo run | replay | bag-info``: the CLI subcommands of the ROS node suite.

Hook into an argparse CLI with :func:`add_subcommands`; each subcommand sets ``func`` (call
``args.func(args)``, which returns the exit code). Standalone: ``python -m
localpbo_ros.commands run ...``. Building the parsers imports no ROS module (``localpbo
bench --help`` stays free of rclpy); each command imports what it needs when it runs.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from localpbo_core.arguments import json_object
from localpbo_core.settings import (
    DEFAULT_ALGORITHM,
    DEFAULT_INITIAL_DESIGN,
    DEFAULT_NOISE_FRACTION,
    DEFAULT_PROBLEM,
    DEFAULT_TIE_THRESHOLD,
)

EXIT_OK, EXIT_RUN_FAILED, EXIT_USAGE = 0, 1, 2


def _json_object(text: str) -> str:
    """A JSON object given on the command line, kept as text (node parameters are text)."""
    json_object(text)
    return text


def add_subcommands(subparsers: Any) -> None:
    """Add ``run``, ``replay`` and ``bag-info`` to an argparse subparsers object."""
    run = subparsers.add_parser(
        "run",
        help="tuning run over ROS topics (optimizer, simulator, oracle, recorder in-process)",
        description="Bring up optimizer, simulator and oracle nodes plus the MCAP recorder in "
        "one process (private context; nothing leaves the process) and tune until the budget "
        f"is spent. Default: {DEFAULT_ALGORITHM} on {DEFAULT_PROBLEM}, budget initial design "
        "+ 10 d (162 on Swimmer). Prints a summary: recommended candidate, incumbent, duels, "
        "bag path. Ctrl-C or SIGTERM stops it cleanly (bag complete, a bridged controller's "
        "parameters restored; --resume continues it) with exit code 130 or 143; 0 done, 1 "
        "failed, 2 refused.",
    )
    run.add_argument("--task", default=DEFAULT_PROBLEM, help="task, e.g. swimmer, hopper")
    run.add_argument(
        "--algorithm",
        default=DEFAULT_ALGORITHM,
        help="e.g. turpbo, sobol, or a preset (an algorithm with options, recorded as if "
        "given explicitly), e.g. prefsqp_all",
    )
    run.add_argument(
        "--budget",
        type=int,
        default=0,
        help="evaluations incl. the initial design (0 = initial design + 10 d)",
    )
    run.add_argument("--seed", type=int, default=0, help="run seed")
    run.add_argument(
        "--initial-design", type=int, default=DEFAULT_INITIAL_DESIGN, help="initial random points"
    )
    run.add_argument(
        "--noise",
        type=float,
        default=DEFAULT_NOISE_FRACTION,
        help="oracle noise std as a fraction of the task's value range",
    )
    run.add_argument(
        "--tie-threshold",
        type=float,
        nargs="?",
        default=None,
        const=DEFAULT_TIE_THRESHOLD,
        metavar="EPS",
        help="indifference threshold eps of the ordinal likelihood: 'can't tell' answers are "
        f"used iff > 0 (default 0, the paper's model, and {DEFAULT_TIE_THRESHOLD} with "
        f"--oracle human; the flag alone: {DEFAULT_TIE_THRESHOLD}, the value for a person "
        "judging)",
    )
    run.add_argument(
        "--indifference",
        type=float,
        default=0.0,
        help="the simulated oracle answers 'can't tell' when its noisy difference is below "
        "this fraction of the value range (needs --tie-threshold > 0; default 0)",
    )
    run.add_argument("--algorithm-options", type=_json_object, default="{}", metavar="JSON")
    run.add_argument(
        "--task-options",
        type=_json_object,
        default="{}",
        metavar="JSON",
        help='e.g. \'{"episode_steps": 200, "value_range": 100}\'',
    )
    run.add_argument(
        "--space",
        default="",
        metavar="FILE",
        help="tune the parameters a space file (YAML) lists instead of --task; needs --bridge "
        "or --example-controller",
    )
    run.add_argument(
        "--bridge",
        type=_json_object,
        default=None,
        metavar="JSON",
        help="evaluate on a running controller node through its parameters (param_bridge_node "
        'parameters), e.g. \'{"target_node": "/my_controller", "score_topic": "/cost"}\'',
    )
    run.add_argument(
        "--example-controller",
        type=_json_object,
        nargs="?",
        const="{}",
        default=None,
        metavar="JSON",
        help="start the worked example's pid_controller_node in this process (optionally with "
        "its parameters as JSON) and bridge to it",
    )
    run.add_argument(
        "--oracle",
        choices=("simulated", "human"),
        default=None,
        help="who answers the duels: the simulated oracle (episode returns plus noise; the "
        "default) or you, in a browser (prints the page's URL and waits for your answers); "
        "--resume keeps the recorded one",
    )
    run.add_argument(
        "--warm-start",
        choices=("auto", "ars", "none"),
        default="auto",
        help="'ars': start from the published ARS policy and tune perturbations of it (task "
        "option around_ars, Hopper and Walker2d), so the episodes last long enough to watch; "
        "'auto' (default): 'ars' with --oracle human on those tasks, else 'none'",
    )
    run.add_argument(
        "--judge",
        type=_json_object,
        default="{}",
        metavar="JSON",
        help="judge_node parameters with --oracle human, e.g. '{\"port\": 8765}' (default: "
        "a free port on 127.0.0.1; answers journaled in OUT/judge/RUN_ID/)",
    )
    run.add_argument(
        "--speculate",
        action=argparse.BooleanOptionalAction,
        default=None,
        help="prepare the next ask for every possible answer while a duel is judged (the "
        "next duel appears at once; the same run either way); default: on with --oracle "
        "human, off otherwise",
    )
    run.add_argument("--failure-policy", choices=("retry", "stop"), default="retry")
    run.add_argument("--out", default="runs", help="directory for the bag")
    run.add_argument("--bag", default=None, help="bag path (default OUT/RUN_ID.mcap)")
    run.add_argument(
        "--max-retries",
        type=int,
        default=2,
        help="retries per duel when an evaluation or answer fails (failure policy retry)",
    )
    run.add_argument("--run-id", default=None, help="run id (default run-<UTC time>)")
    run.add_argument(
        "--resume",
        default=None,
        metavar="BAG",
        help="continue the run recorded in BAG (its config rules); the new bag "
        "holds the old history plus the rest, each duel once",
    )
    run.add_argument("--no-progress", action="store_true", help="hide the progress bar")
    run.set_defaults(func=cmd_run, handles_signals=True)

    replay = subparsers.add_parser(
        "replay",
        help="re-publish a bag with its timing, or --verify it offline",
        description="Publish the recorded topics with their original timing and QoS (like "
        "ros2 bag play), or with --verify rebuild the optimizer from the recorded config and "
        "outcomes and check it proposes exactly the recorded candidates.",
    )
    replay.add_argument("bag", help=".mcap file")
    replay.add_argument(
        "--verify",
        action="store_true",
        help="offline check; prints OK or the first mismatch (exit 1)",
    )
    replay.add_argument("--rate", type=float, default=1.0, help="playback speed factor")
    replay.add_argument("--loop", action="store_true", help="play again and again (Ctrl-C)")
    replay.add_argument("--topics", nargs="+", default=None, help="only these topics")
    replay.set_defaults(func=cmd_replay)

    info = subparsers.add_parser("bag-info", help="summarise a bag (topics, counts, time span)")
    info.add_argument("bag", help=".mcap file")
    info.set_defaults(func=cmd_bag_info)


def tie_threshold_of(args: argparse.Namespace) -> float:
    """``--tie-threshold``, else 0 (the paper's model), or ``DEFAULT_TIE_THRESHOLD`` when a
    person judges (``--oracle human``: people need a "can't tell")."""
    if args.tie_threshold is not None:
        return float(args.tie_threshold)
    return DEFAULT_TIE_THRESHOLD if getattr(args, "oracle", "") == "human" else 0.0


def speculate_of(args: argparse.Namespace) -> bool:
    """``--speculate``/``--no-speculate``, else on when a person judges (a person waits for
    each decision; a simulated oracle does not, and speculation would only cost CPU)."""
    if args.speculate is not None:
        return bool(args.speculate)
    return getattr(args, "oracle", "") == "human"


def warm_start_of(args: argparse.Namespace) -> tuple[str, str]:
    """``--algorithm-options`` and ``--task-options`` with ``--warm-start``: for ``ars`` the
    task's box centred on its ARS policy (``around_ars``, radius ``ARS_RADII``) and that policy
    (θ = 0.5) as the warm start, unless the options already set a box or a warm start.

    Raises:
        ValueError: ``--warm-start ars`` on a task without an ARS policy.
    """
    from localpbo_sims.tasks import ARS_RADII, VALUE_RANGES

    choice = getattr(args, "warm_start", "none")
    if choice == "auto":
        person = getattr(args, "oracle", None) == "human"
        choice = "ars" if person and args.task in ARS_RADII and not args.space else "none"
    if choice == "none":
        return args.algorithm_options, args.task_options
    if args.task not in ARS_RADII or args.space:
        raise ValueError(
            f"--warm-start ars: no ARS policy for {args.task!r}; valid: hopper, walker2d"
        )
    task_options = json.loads(args.task_options)
    algorithm_options = json.loads(args.algorithm_options)
    if not {"around_ars", "weight_low", "weight_high"} & set(task_options):
        task_options["around_ars"] = ARS_RADII[args.task]
        # the noise scale a simulated oracle needs: the default box's (a person ignores it)
        task_options.setdefault("value_range", VALUE_RANGES[args.task])
    if "around_ars" in task_options and "warm_start" not in algorithm_options:
        from localpbo_sims import make_task

        dim = make_task(args.task).dim
        algorithm_options["warm_start"] = [0.5] * dim  # the box's centre: the ARS policy
    return json.dumps(algorithm_options), json.dumps(task_options)


def run_settings(args: argparse.Namespace) -> dict[str, Any]:
    """Optimizer-node parameters from ``run`` arguments.

    Raises:
        ValueError: ``--warm-start ars`` on a task without an ARS policy.
    """
    run_id = args.run_id or time.strftime("run-%Y%m%dT%H%M%SZ", time.gmtime())
    algorithm_options, task_options = warm_start_of(args)
    return {
        "run_id": run_id,
        "algorithm": args.algorithm,
        "task": args.task,
        "budget": args.budget,
        "seed": args.seed,
        "initial_design": args.initial_design,
        "noise_fraction": float(args.noise),
        "tie_threshold": tie_threshold_of(args),
        "indifference": float(args.indifference),
        "algorithm_options": algorithm_options,
        "task_options": task_options,
        "failure_policy": args.failure_policy,
        "space": args.space,
        "speculate": speculate_of(args),
        "max_retries": args.max_retries,
        "oracle": args.oracle or "simulated",
    }


def cmd_run(args: argparse.Namespace) -> int:
    """``localpbo run``.

    SIGINT or SIGTERM stops the run cleanly (``run_suite``'s ``stop``): the summary says
    ``stopped`` and how to continue, and the process exits with 128 + the signal (130, 143)
    at once after it (the interpreter's finalization skipped, as the nodes do). Exit codes
    otherwise: 0 done, 1 failed, 2 refused.
    """
    from localpbo_core.stopping import exit_now, shell_code, stop_requests
    from localpbo_ros.driver import judged_by_person
    from localpbo_ros.params import ParameterError
    from localpbo_ros.replay import resumable
    from localpbo_ros.suite import StoppedEarly, default_bag, run_suite

    if args.resume is not None:
        args.warm_start = "none"  # the recorded config rules
        try:
            recorded_run = resumable(args.resume)
            recorded = recorded_run.config
        except (OSError, ValueError) as exc:
            print(f"localpbo run: --resume: {exc}", file=sys.stderr)
            return EXIT_USAGE
        if recorded_run.ends_early:
            print(
                f"localpbo run: --resume: {args.resume}: {recorded_run.ends_early}; "
                "continuing from what was read",
                file=sys.stderr,
            )
        if judged_by_person(recorded):
            if args.oracle == "simulated":
                print(
                    f"localpbo run: --oracle simulated: run {recorded.run_id} is judged by a "
                    "person; resume it with --oracle human (or without --oracle)",
                    file=sys.stderr,
                )
                return EXIT_USAGE
            args.oracle = "human"
    try:
        settings = run_settings(args)
    except ValueError as exc:
        print(f"localpbo run: {exc}", file=sys.stderr)
        return EXIT_USAGE
    if args.resume is not None:
        settings["run_id"] = recorded.run_id
    elif args.space:  # a refused space file is named before anything starts
        from localpbo_core.space import load_space
        from localpbo_core.validation import SettingError

        try:
            load_space(args.space)
        except SettingError as exc:
            print(f"localpbo run: --space: {exc.field}: {exc.reason}", file=sys.stderr)
            return EXIT_USAGE
    bag = Path(args.bag) if args.bag else default_bag(args.out, settings["run_id"])
    if args.resume is not None and bag.resolve() == Path(args.resume).resolve():
        bag = bag.with_name(bag.stem + "-resumed.mcap")
    bar = None
    progress = None
    if not args.no_progress:
        from tqdm import tqdm

        bar = tqdm(total=0, unit="eval", desc="localpbo run", dynamic_ncols=True)

        def progress(used: int, budget: int) -> None:
            assert bar is not None
            if (used, budget) != (bar.n, bar.total):
                bar.total = budget
                bar.n = used
                bar.refresh()

    bridge, controllers = _bridge_of(args)
    if args.space and bridge is None and args.resume is None:
        print("localpbo run: --space needs --bridge or --example-controller", file=sys.stderr)
        return EXIT_USAGE
    judge = None
    if args.oracle == "human":
        # a resumed run keeps the first run's journal, secret and port (next to its bag)
        folder = (bag if args.resume is None else Path(args.resume)).parent / "judge"
        judge = {"state_dir": str(folder), **json.loads(args.judge)}

    def show_url(url: str) -> None:
        text = f"judge the duels at {url}"
        if bar is not None:
            bar.write(text)
        else:
            print(text, flush=True)

    with stop_requests() as stop:
        try:
            summary = run_suite(
                settings,
                bag,
                resume=args.resume,
                on_progress=progress,
                bridge=bridge,
                controllers=controllers,
                judge=judge,
                on_url=show_url,
                stop=stop,
            )
        except ParameterError as exc:
            print(f"localpbo run: {exc}", file=sys.stderr)
            return EXIT_USAGE
        except StoppedEarly:
            summary = None
        finally:
            if bar is not None:
                bar.close()
        if summary is None:
            print(
                f"localpbo run: stopped by {stop.signal_name} before the run started; "
                "no bag written",
                file=sys.stderr,
            )
            exit_now(shell_code(stop.signum))
        print(summary.format())
        if stop.is_set() and summary.state != "done":
            exit_now(shell_code(stop.signum))
    return EXIT_OK if summary.state == "done" else EXIT_RUN_FAILED


def _bridge_of(args: argparse.Namespace) -> tuple[dict[str, Any] | None, list[Any]]:
    """Bridge parameters and in-process controller factories from ``run`` arguments."""
    bridge = None if args.bridge is None else dict(json.loads(args.bridge))
    if args.example_controller is None:
        return bridge, []
    from localpbo_examples.pid_controller_node import BRIDGE_SETTINGS, PidControllerNode
    from rclpy.context import Context

    overrides = dict(json.loads(args.example_controller))

    def controller(ctx: Context) -> Any:
        return PidControllerNode(context=ctx, overrides=overrides)

    return {**BRIDGE_SETTINGS, **(bridge or {})}, [controller]


def cmd_replay(args: argparse.Namespace) -> int:
    """``localpbo replay``."""
    if args.verify:
        from localpbo_ros.replay import verify

        try:
            report = verify(args.bag)
        except (OSError, ValueError) as exc:
            print(f"localpbo replay: {exc}", file=sys.stderr)
            return EXIT_USAGE
        print(report.format())
        return EXIT_OK if report.ok else EXIT_RUN_FAILED
    from localpbo_ros.bagtools import require_bag

    try:
        require_bag(args.bag)
    except (OSError, ValueError) as exc:
        print(f"localpbo replay: {exc}", file=sys.stderr)
        return EXIT_USAGE
    import rclpy
    from rclpy.context import Context
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node

    from localpbo_ros.dds import host_scope
    from localpbo_ros.replay import play

    host_scope()
    ctx = Context()
    rclpy.init(context=ctx)
    node = Node("localpbo_replay", context=ctx, start_parameter_services=False)
    executor = SingleThreadedExecutor(context=ctx)
    executor.add_node(node)
    try:
        sent = play(
            args.bag,
            node,
            executor,
            rate=args.rate,
            loops=0 if args.loop else 1,
            topics=args.topics,
        )
        print(f"published {sent} messages from {args.bag}")
        return EXIT_OK
    except BrokenPipeError:
        raise  # the reader of stdout went away: main ends quietly
    except (OSError, ValueError) as exc:
        print(f"localpbo replay: {exc}", file=sys.stderr)
        return EXIT_USAGE
    except KeyboardInterrupt:
        return EXIT_OK
    finally:
        executor.shutdown()
        node.destroy_node()
        rclpy.shutdown(context=ctx)


def cmd_bag_info(args: argparse.Namespace) -> int:
    """``localpbo bag-info``: the file (complete: closed cleanly, or where it ends early),
    its topics, and for a run's bag whether the run finished (n of budget evaluations)."""
    from localpbo_msgs_py.bag import summarize
    from localpbo_ros.bagtools import (
        duel_timings,
        history_problem,
        judged_by,
        load_run,
        outcome_counts,
        require_bag,
    )
    from localpbo_ros.completeness import format_statuses, last_statuses

    try:
        require_bag(args.bag)
        summary = summarize(args.bag)
    except (OSError, ValueError) as exc:
        print(f"localpbo bag-info: {exc}", file=sys.stderr)
        return EXIT_USAGE
    print(summary.format())
    try:
        run = load_run(args.bag)
    except ValueError:  # not a run's bag (no run config): topics only
        return EXIT_OK
    print(f"run finished: {run.finished}")
    problem = history_problem(run)
    if problem:
        print(f"not one run's record: {problem}")
    print(outcome_counts(run).format())
    if people := judged_by(run):
        print(people)
    for timing in duel_timings(run):
        print(timing.format())
    for line in format_statuses(last_statuses(args.bag, run.config.run_id)):
        print(line)  # every node's state and counters (its drops among them)
    return EXIT_OK


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m localpbo_ros.commands run|replay|bag-info ...`` (a closed stdout pipe ends
    it quietly, :func:`localpbo_core.pipes.quiet_on_closed_pipe`)."""
    from localpbo_core.pipes import quiet_on_closed_pipe

    parser = argparse.ArgumentParser(prog="localpbo")
    add_subcommands(parser.add_subparsers(dest="command", required=True))
    args = parser.parse_args(argv)
    return quiet_on_closed_pipe(lambda: int(args.func(args)))


if __name__ == "__main__":
    sys.exit(main())
