"""What the stored runs cover of the bundled experiment specs, and what completing them takes.

The results page's **Coverage** section: per spec, its groups (one problem, variant and
algorithm) stored with the paper's 10 seeds (Sec. 6, "10 runs"), the groups still missing
and, of those, the ones the paper itself did not run (no time in its App. E table); then
the ``localpbo sweep`` commands that store exactly the missing groups (:func:`completion_plan`)
and what each costs in core-hours, estimated from the nearest stored runs
(:func:`group_cost`).
"""

from __future__ import annotations

import itertools
import json
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from localpbo_core.experiments.paper import PAPER_SECONDS, PAPER_SEEDS, paper_seconds, problem_key
from localpbo_core.presets import PRESETS

if TYPE_CHECKING:
    from localpbo_core.report import StoredRun


def group_list(keys: Sequence[tuple[str, str, str]], total: int, algorithms: int = 0) -> str:
    """(problem, variant, algorithm) keys as "problem (variant): a, b; ..." ("every group"
    when they are all ``total`` groups of a spec; "every algorithm" for a problem that misses
    all its ``algorithms``)."""
    if not keys:
        return ""
    if len(keys) == total:
        return "every group"
    by_problem: dict[str, list[str]] = {}
    for problem, variant, algorithm in sorted(keys):
        label = problem + (f" ({variant})" if variant else "")
        by_problem.setdefault(label, []).append(algorithm)
    return "; ".join(
        f"{p}: {'every algorithm' if len(a) == algorithms else ', '.join(a)}"
        for p, a in by_problem.items()
    )


COVERAGE_SEEDS = PAPER_SEEDS
"""The seeds a group needs to count as stored: the paper's 10 runs per experiment (Sec. 6)."""


PAPER_SPECS = (
    "synthetic",
    "gp_within",
    "gp_out_of_model",
    "policy_warm_start",
    "policy_no_warm_start",
    "ablation_prefsqp_line_search",
    "ablation_turpbo_acquisition",
    "ablation_qeubo_batch",
    "ablation_noise",
)
"""The bundled specs of the paper's experiments (Sec. 6, App. D.4-D.7)."""


def bundled_specs() -> list[str]:
    """The names of the bundled experiment specs (``localpbo_core/experiments/*.yaml``) but
    the CI spec ``tiny``."""
    folder = Path(__file__).resolve().parent
    return sorted(p.stem for p in folder.glob("*.yaml") if p.stem != "tiny")


def coverage_specs(runs: Sequence[StoredRun]) -> list[str]:
    """The specs the coverage table lists: the paper's (:data:`PAPER_SPECS`), stored or not,
    and every other bundled spec with stored runs among ``runs``."""
    stored = {r.spec for r in runs}
    return sorted(set(PAPER_SPECS) | (stored & set(bundled_specs())))


def _stored_seeds(runs: Sequence[StoredRun]) -> dict[tuple[str, str, str, str], set[int]]:
    """Seeds stored per (spec, problem, variant, algorithm) label."""
    seeds: dict[tuple[str, str, str, str], set[int]] = {}
    for r in runs:
        seeds.setdefault((r.spec, r.problem_label, r.variant, r.algorithm_label), set()).add(r.seed)
    return seeds


def _not_in_paper(spec: Any, missing: Sequence[tuple[str, str, str]]) -> list[tuple[str, str, str]]:
    """The groups among ``missing`` of a main experiment whose algorithm the paper's App. E
    table has no time for on that problem (the paper did not run them, e.g. HB-EI and GIPBO
    beyond 32 dimensions)."""
    entries = {p.label: p for p in spec.problems}
    out: list[tuple[str, str, str]] = []
    for p, v, a in missing:
        entry = entries[p]
        key = problem_key(entry.name, dict(entry.options), spec.within_model)
        if not v and key in PAPER_SECONDS and paper_seconds(key, a) is None:
            out.append((p, v, a))
    return out


def _shown(path: Path) -> str:
    """``path`` relative to the repository when inside it (the page reads the same from any
    checkout and any working directory), else as given."""
    from localpbo_core.provenance import ROOT

    try:
        return path.resolve().relative_to(ROOT.resolve()).as_posix()
    except ValueError:
        return path.as_posix()


@dataclass(frozen=True)
class MissingGroup:
    """A group (spec, problem, variant, algorithm labels) without every seed stored."""

    spec: str
    problem: str
    variant: str
    algorithm: str
    runs: int
    """Its runs not stored."""
    within_model: bool
    """Whether the spec's runs know the true hyperparameters (within-model GP paths)."""
    problem_name: str
    """The registered problem behind the label (e.g. ``gp_sample``)."""
    dim: int | None
    """The problem's ``dim`` option, if it has one."""
    copies: int = 0
    """Of its runs not stored, those another spec stored with the same settings: the
    command's ``--reuse`` copies them instead of computing them."""


@dataclass(frozen=True)
class Completion:
    """One ``localpbo sweep`` command of :func:`completion_plan` and the runs it stores."""

    words: tuple[str, ...]
    groups: tuple[MissingGroup, ...]

    @property
    def command(self) -> str:
        return " ".join(self.words)


def completion_commands(
    runs: Sequence[StoredRun], specs: Sequence[str], inputs: Sequence[str | Path]
) -> list[str]:
    """The command lines of :func:`completion_plan`."""
    return [c.command for c in completion_plan(runs, specs, inputs)]


def completion_plan(
    runs: Sequence[StoredRun], specs: Sequence[str], inputs: Sequence[str | Path]
) -> list[Completion]:
    """``localpbo sweep`` commands that store the groups of ``specs`` missing at
    :data:`COVERAGE_SEEDS`, except groups of the paper's specs (:data:`PAPER_SPECS`) that the
    paper did not run (:func:`_not_in_paper`).

    A command's problems × variants × algorithms are missing groups exactly (groups that share
    their missing algorithms and variants share a command), so it runs nothing else: a sweep
    skips stored runs. Its ``--out`` is the folder under ``inputs`` (the report's run folders,
    relative to the repository when inside it) that holds the spec's runs, the first input's
    when none does. ``--reuse`` names the folder of every other spec that stored a run with
    the settings of one of the command's missing runs (options completed by their defaults,
    as ``localpbo sweep --reuse`` compares them), and the groups count those runs as copies:
    e.g. the paper specs' TuRPBO runs that a ``beyond_*`` spec compares with, or the Sobol and
    GLISp runs of the other model setting on the GP paths (they take no GP hyperparameters,
    so a within-model run is its out-of-model twin)."""
    from localpbo_core.experiments import load_spec
    from localpbo_core.run_documents import settings_document

    seeds = _stored_seeds(runs)
    wanted = set(COVERAGE_SEEDS)
    ordered = sorted(wanted)
    consecutive = ordered == list(range(ordered[0], ordered[-1] + 1))
    span = f"{ordered[0]}-{ordered[-1]}" if consecutive else ",".join(map(str, ordered))
    roots = [_shown(Path(p)) for p in inputs]
    candidates: dict[str, list[StoredRun]] = {}
    for r in runs:
        settings = r.settings
        cheap = _cheap_key(
            settings.get("algorithm"),
            settings.get("problem"),
            settings.get("problem_options"),
            r.seed,
        )
        candidates.setdefault(cheap, []).append(r)
    known: dict[str, dict[str, object]] = {}

    def folder(name: str) -> str:
        held = [
            shown
            for shown, p in zip(roots, inputs, strict=True)
            if (Path(p) / name / "runs").is_dir()
        ]
        return f"{(held or roots)[0]}/{name}"

    plan = []
    for name in specs:
        spec = load_spec(name, validate=False)
        copies: dict[tuple[str, str, str], int] = {}
        entries = {e.label: e for e in spec.problems}
        kinds = {e.label: e.name for e in spec.algorithms}
        missing = [k for k in spec.groups() if seeds.get((spec.name, *k), set()) & wanted != wanted]
        skipped = set(_not_in_paper(spec, missing)) if spec.name in PAPER_SPECS else set()
        algorithms: dict[tuple[str, str], set[str]] = {}
        for key in missing:
            if key not in skipped:
                algorithms.setdefault(key[:2], set()).add(key[2])
        problems: dict[tuple[tuple[str, ...], str], list[str]] = {}
        for (p, v), names in algorithms.items():
            problems.setdefault((tuple(sorted(names)), v), []).append(p)
        variants: dict[tuple[tuple[str, ...], tuple[str, ...]], list[str]] = {}
        for (algs, v), labels in problems.items():
            variants.setdefault((algs, tuple(sorted(labels))), []).append(v)
        for (algs, ps), vs in sorted(variants.items(), key=lambda kv: (kv[0][1], kv[0][0])):
            donors: dict[tuple[str, str, str], set[str]] = {}
            for p, v, a in itertools.product(ps, sorted(vs), algs):
                for seed in sorted(wanted - seeds.get((spec.name, p, v, a), set())):
                    cheap = _cheap_key(kinds[a], entries[p].name, entries[p].options, seed)
                    near = [r for r in candidates.get(cheap, []) if r.spec != spec.name]
                    if not near:
                        continue  # no stored run to compare with: resolving may build the problem
                    planned = spec.runs([p], [a], [v], [seed])  # empty: not a seed of spec
                    keys = {_settings_key(settings_document(r.settings), known) for r in planned}
                    keys.discard("")
                    found = {r.spec for r in near if _settings_key(r.settings, known) in keys}
                    if not found:
                        continue
                    donors.setdefault((p, v, a), set()).update(found)
                    copies[(p, v, a)] = copies.get((p, v, a), 0) + 1
            words = ["localpbo", "sweep", spec.name, "--out", folder(spec.name)]
            words += ["--problems", ",".join(ps), "--algorithms", ",".join(algs)]
            if any(vs):
                words += ["--variants", ",".join(sorted(vs))]
            words += ["--seeds", span]
            for other in sorted(set().union(*donors.values())):
                words += ["--reuse", folder(other)]
            groups = tuple(
                MissingGroup(
                    spec.name,
                    p,
                    v,
                    a,
                    len(wanted - seeds.get((spec.name, p, v, a), set())),
                    spec.within_model,
                    entries[p].name,
                    _dim(entries[p].options),
                    copies.get((p, v, a), 0),
                )
                for p in ps
                for v in sorted(vs)
                for a in algs
            )
            plan.append(Completion(tuple(words), groups))
    return plan


def _settings_key(settings: dict[str, Any], known: dict[str, dict[str, object]]) -> str:
    """A run's settings as ``localpbo sweep --reuse`` compares them
    (:func:`~localpbo_core.sweep.effective_settings`, ``known`` its defaults cache), as one
    string; empty for an unregistered algorithm."""
    from localpbo_core.sweep import effective_settings

    effective = effective_settings(settings, known)
    return "" if effective is None else json.dumps(effective, sort_keys=True, default=str)


def _cheap_key(algorithm: Any, problem: Any, options: Any, seed: int) -> str:
    """What a run's settings must share with a stored run's to be the same run, read without
    resolving them: algorithm, problem, its options (a spec's seed placeholder replaced) and
    seed."""
    from localpbo_core.experiments.spec import SEED_TOKEN

    options = {k: seed if v == SEED_TOKEN else v for k, v in dict(options or {}).items()}
    return json.dumps([algorithm, problem, options, seed], sort_keys=True, default=str)


def run_cost(run: StoredRun) -> float:
    """What a stored run cost a core: its CPU seconds, or for a run stored before runs
    recorded them its optimizer seconds (evaluations excluded, wall time under whatever load
    the machine had)."""
    return run.optimizer_seconds if run.cpu_seconds is None else run.cpu_seconds


def _dim(options: Any) -> int | None:
    """A problem's ``dim`` option, if it has an integer one."""
    dim = dict(options).get("dim")
    return dim if isinstance(dim, int) else None


def group_cost(runs: Sequence[StoredRun], group: MissingGroup) -> tuple[float, str] | None:
    """Seconds a core needs for one more run of ``group``, estimated as the mean
    :func:`run_cost` of the stored runs nearest to it, and which runs those are: the group's
    own; else the same spec's runs of the problem and algorithm in other variants; else the
    same spec's runs of the algorithm and variant on problems of the same kind and dimension
    (e.g. a GP path of the same d with another lengthscale); else other specs' runs of the
    same problem label and algorithm in the same model setting; else those in the other
    setting (within model a GP method learns no hyperparameters, so these understate its
    cost); else, for a preset (``localpbo_core/presets.py``: an algorithm with options), the
    runs of the same problem label by the preset's algorithm, same model setting first (the
    options change how the algorithm spends its steps, not what one step costs, so read these
    as a guide). Runs with CPU seconds are preferred over those without at each step. None when
    no such run is stored."""
    g = group
    same = [r for r in runs if (r.problem_label, r.algorithm_label) == (g.problem, g.algorithm)]
    kin = [
        r
        for r in runs
        if g.dim is not None
        and (r.spec, r.algorithm_label, r.variant) == (g.spec, g.algorithm, g.variant)
        and r.problem_label != g.problem
        and (r.settings["problem"], _dim(r.settings["problem_options"])) == (g.problem_name, g.dim)
    ]
    preset = PRESETS.get(g.algorithm)
    base_algorithm = preset.algorithm if preset is not None else None
    base = [r for r in runs if (r.problem_label, r.algorithm_label) == (g.problem, base_algorithm)]
    of_base = f"of {base_algorithm}, the preset's algorithm"
    other = ", the other model setting"
    steps: list[tuple[str, list[StoredRun]]] = [
        ("of the group", [r for r in same if (r.spec, r.variant) == (g.spec, g.variant)]),
        ("of other variants", [r for r in same if r.spec == g.spec and r.variant != g.variant]),
        ("of " + ", ".join(sorted({r.problem_label for r in kin})), kin),
        ("", [r for r in same if r.spec != g.spec and r.within_model == g.within_model]),
        (other, [r for r in same if r.spec != g.spec and r.within_model != g.within_model]),
        (of_base, [r for r in base if r.within_model == g.within_model]),
        (of_base + other, [r for r in base if r.within_model != g.within_model]),
    ]
    for where, found in steps:
        if not found:
            continue
        timed = [r for r in found if r.cpu_seconds is not None]
        basis = timed or found
        seconds = float(np.mean([run_cost(r) for r in basis]))
        what = "CPU seconds" if timed else "optimizer seconds"
        n = f"{len(basis)} run{'s' if len(basis) != 1 else ''}"
        specs = ", ".join(sorted({r.spec for r in basis}))
        source = where if where.startswith("of ") else f"of {specs}{where}"
        return seconds, f"{n} {source}; {what}"
    return None


def _hours(seconds: float) -> str:
    return f"{seconds / 3600:.1f}"


def completion_costs(runs: Sequence[StoredRun], plan: Sequence[Completion]) -> list[str]:
    """A table of the core-hours each command of ``plan`` needs (:func:`group_cost` per
    missing group, its copies free) and a sentence with the total; nothing when ``plan`` is
    empty."""
    if not plan:
        return []
    lines = [
        "| command | runs | core-hours | per run, estimated from |",
        "| ---: | ---: | ---: | --- |",
    ]
    total_runs, total_seconds, unknown, total_copies = 0, 0.0, 0, 0
    for i, c in enumerate(plan, 1):
        seconds, cells, n_runs, open_runs, computed = 0.0, [], 0, 0, 0
        for g in c.groups:
            name = "/".join(x for x in (g.problem, g.variant, g.algorithm) if x)
            n = g.runs - g.copies
            n_runs += g.runs
            total_copies += g.copies
            if not n:
                cells.append(f"{name}: {g.copies} copied")
                continue
            head = f"{name}: {g.copies} copied, " if g.copies else f"{name}: "
            computed += n
            cost = group_cost(runs, g)
            if cost is None:
                open_runs += n
                cells.append(head + "no stored run to estimate from")
                continue
            seconds += n * cost[0]
            cells.append(head + f"{cost[0] / 60:.3g} min ({cost[1]})")
        if computed and open_runs == computed:
            hours = "?"
        else:
            hours = _hours(seconds) + (" + ?" if open_runs else "")
        lines.append(f"| {i} | {n_runs} | {hours} | {'; '.join(cells)} |")
        total_runs += n_runs
        total_seconds += seconds
        unknown += open_runs
    rest = f", besides {unknown} runs with nothing stored to estimate from" if unknown else ""
    of = f" ({total_copies} of them copies, which cost nothing)" if total_copies else ""
    lines += [
        "",
        f"In all {total_runs} runs{of}, about {_hours(total_seconds)} core-hours{rest}: one "
        "run uses one core, so a machine or cluster with c free cores needs about 1/c of that "
        "in wall time. The estimates come from stored runs of other days and loads, and where "
        "runs did not record CPU seconds their optimizer seconds stand in, which leave out the "
        "evaluations (on the policy tasks, the episodes): read them as a guide.",
    ]
    return lines


def coverage_table(runs: Sequence[StoredRun], specs: Sequence[str]) -> list[str]:
    """Per bundled spec: its groups (problem × variant × algorithm) and runs at
    :data:`COVERAGE_SEEDS`, how many of them are stored in ``runs``, and the groups not
    stored with every one of those seeds, split by whether the paper ran them (a group of a
    main experiment whose algorithm the paper's App. E table has no time for on that problem,
    e.g. HB-EI and GIPBO beyond 32 dimensions, was not run in the paper)."""
    from localpbo_core.experiments import load_spec

    seeds = _stored_seeds(runs)
    wanted = set(COVERAGE_SEEDS)
    lines = [
        f"| spec | paper | groups with seeds {min(wanted)}–{max(wanted)} | runs "
        "| not stored with all those seeds | of those, not in the paper's App. E table |",
        "| --- | --- | ---: | ---: | --- | --- |",
    ]
    for name in specs:
        spec = load_spec(name, validate=False)
        keys = spec.groups()
        have = {k: seeds.get((spec.name, *k), set()) & wanted for k in keys}
        complete = [k for k in keys if have[k] == wanted]
        stored = sum(len(v) for v in have.values())
        missing = [k for k in keys if have[k] != wanted]
        unpaper = _not_in_paper(spec, missing)
        n = len(spec.algorithms)
        lines.append(
            f"| {spec.name} | {spec.paper} | {len(complete)} of {len(keys)} | {stored} of "
            f"{len(keys) * len(wanted)} | {group_list(missing, len(keys), n) or '—'} | "
            f"{group_list(unpaper, len(keys), n) or '—'} |"
        )
    return lines


def checkpoint_table(folders: Sequence[str | Path]) -> list[str]:
    """The runs under way kept in checkpoints (``checkpoints/*.ckpt.gz`` below ``folders``,
    :mod:`localpbo_core.checkpoints`): per checkpoint its spec, run, evaluations kept of the
    budget, the CPU seconds behind it and whether today's code continues it (the same run
    sources' and algorithm's digests); nothing when there is none."""
    from localpbo_core.checkpoints import CHECKPOINT_SUFFIX, CheckpointError, code_digests
    from localpbo_core.checkpoints import read_header as read_checkpoint_header

    rows = []
    found = {
        path
        for folder in map(Path, folders)
        if folder.is_dir()
        for path in folder.rglob(f"*{CHECKPOINT_SUFFIX}")
        if path.parent.name == "checkpoints"
    }
    for path in sorted(found):
        run_id = path.name[: -len(CHECKPOINT_SUFFIX)]
        try:
            header = read_checkpoint_header(path)
            done, budget = int(header["evaluations"]), int(header["budget"])
            cpu = float(header["cpu_seconds"])
            algorithm = str(header["settings"]["algorithm"])
        except (CheckpointError, KeyError, TypeError, ValueError):
            rows.append(f"| {path.parent.parent.name} | {run_id} | unreadable | | no |")
            continue
        today = "yes" if header.get("code") == code_digests(algorithm) else "no: other code"
        rows.append(
            f"| {path.parent.parent.name} | {run_id} | {done} of {budget} | {cpu:.0f} | {today} |"
        )
    if not rows:
        return []
    return [
        "Runs under way, kept in checkpoints: the commands above continue each from there "
        '(docs/reproducing.md, "Checkpoints"), and the costs below count them whole.',
        "",
        "| spec | run | evaluations kept | CPU s behind it | continues with today's code |",
        "| --- | --- | ---: | ---: | --- |",
        *rows,
        "",
    ]
