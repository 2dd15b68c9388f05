"""Command-line values shared by the ``localpbo`` command and the modules that re-read its
commands: run seeds (``0-4``), ``--option`` items, JSON objects, the flag of each run setting,
and the ``report`` subcommand's parser (the results page's command is parsed by it).

Nothing here imports the command itself (:mod:`localpbo_core.cli`), sweeps or reports: they
import this module.
"""

from __future__ import annotations

import argparse
import ast
import json
from collections.abc import Sequence

from localpbo_core.optimizers.registry import optimizer_options
from localpbo_core.presets import expand

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


def parse_options(items: Sequence[str], algorithms: Sequence[str]) -> dict[str, dict[str, object]]:
    """``key=value`` (every algorithm that accepts ``key``) or ``alg.key=value``; ``alg`` may
    be a preset (:mod:`localpbo_core.presets`, whose labels may hold a dot, e.g.
    ``hybrid_c0.5.confidence=0.4``), which accepts its algorithm's options."""
    per_alg: dict[str, dict[str, object]] = {a: {} for a in algorithms}
    for item in items:
        if "=" not in item:
            raise ValueError(f"--option: expected key=value, got {item!r}")
        key, value = item.split("=", 1)
        key = key.strip()
        parsed = _parse_value(value.strip())
        targets = list(algorithms)
        named = [a for a in algorithms if key.startswith(a + ".")]
        if named:
            alg = max(named, key=len)
            key = key[len(alg) + 1 :]
            targets = [alg]
        elif "." in key:
            alg = key.split(".", 1)[0]
            raise ValueError(f"--option {item!r}: algorithm {alg!r} is not in --algorithm")
        accepted = [a for a in targets if key in optimizer_options(expand(a, {})[0])]
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


def add_report_command(sub: argparse._SubParsersAction) -> None:
    """The ``report`` subcommand (:mod:`localpbo_core.report`) and its arguments."""
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
    report.add_argument(
        "--complete-seeds",
        default=None,
        metavar="SEEDS",
        help="tabulate only these seeds (e.g. 0-9), and a group (spec, problem, variant, "
        "algorithm) only once all of them are stored; the coverage table still counts every "
        "stored run (default: every run)",
    )


def report_parser() -> argparse.ArgumentParser:
    """A parser of ``localpbo report ...`` alone (argument vectors start with ``report``)."""
    parser = argparse.ArgumentParser(prog="localpbo")
    add_report_command(parser.add_subparsers(dest="command", required=True))
    return parser
