"""Which algorithm to run: every algorithm over the paper's 18 main problems (Sec. 6), the
paper's algorithms and ours (the ``beyond_*`` specs) side by side, and the default the
evidence chooses.

**Problems** (:data:`MAIN_PROBLEMS`): the main experiments of Sec. 6 — the synthetic
functions Hartmann 6, Rosenbrock 16, Levy 32, Styblinski-Tang 64 (App. D.5), the GP sample
paths with d in {8, 16, 32} and lengthscale in {0.1, 0.5}, within and out of model (App.
D.4), and the linear policies Hopper and Walker2d with warm start (App. D.6).

**Merging**: a problem's runs are those of its paper spec (:data:`MAIN_PROBLEMS`), joined by
the runs of the ``beyond_*`` specs with the same problem label and the same conditions for
the seed: problem and its options, budget, initial design, noise fraction, tie threshold,
indifference and the within-model flag (:func:`conditions`). Runs of an ablation variant are
left out. An algorithm label the paper spec has keeps the paper spec's runs (a ``beyond_*``
spec stores copies of them, ``localpbo sweep --reuse``); a label only ``beyond_*`` specs have
takes the runs of the first such spec by name. An algorithm counts on a problem only with
every one of the paper's 10 seeds (:data:`localpbo_core.experiments.paper.PAPER_SEEDS`), and only
those seeds are used, so every comparison is paired by seed.

**Per algorithm** (:func:`standings`), with the report's statistics
(:func:`localpbo_core.report.compare`, :func:`~localpbo_core.report.paired_wilcoxon`,
:func:`~localpbo_core.report.holm`):

* problems run (of 18);
* best or tied, final best-seen and final cumulative (App. D.1 metrics): problems where it has
  the highest mean, or is not significantly different from the algorithm that has it (two-sided
  paired Wilcoxon by seed against the best mean, Holm-corrected over the problem's algorithms,
  alpha) — the count of the claim "TuRPBO is the most robust overall"
  (:mod:`localpbo_core.experiments.claims`);
* significantly above / below TuRPBO (final best-seen): a two-sided paired Wilcoxon test of
  the two on each problem both ran, Holm-corrected over those problems, adjusted p < alpha;
  the direction is that of the means;
* optimizer time relative to TuRPBO's: the geometric mean over the problems both ran of the
  ratio of mean stored optimizer seconds per run. Stored seconds were measured on different
  days under different machine loads, so the ratio is a rough guide.

**The default chosen by the evidence** (:func:`evidence_choice`): among the algorithms run on
all 18 problems, the one best or tied (final best-seen) on the most; ties broken by the
count in final cumulative, then by name. ``localpbo run`` and the optimizer node default to
:data:`localpbo_core.settings.DEFAULT_ALGORITHM`; the page says whether the two agree, and
the test suite fails when they do not. A label of a configured variant can be the default
because the ``beyond_*`` specs name their variants by preset (:mod:`localpbo_core.presets`).

**What a choice between two algorithms could reach** (:func:`pair_reach`): for every pair of
algorithms, the problems where either is best or tied (final best-seen; final cumulative). A
hybrid that picks one of two algorithms per problem (e.g. TuRPBO's region or GIPBOr's local
steps) is best or tied at most there, and only if it always picks the right one: hindsight that
a real hybrid has to replace by what its own duels tell it. So the count bounds any such
selector from above, and a goal beyond every pair's count is beyond every selector of two
stored algorithms.

**The hybrid's goal** (:data:`HYBRID_GOALS`): best or tied on at least 16 of the 18 problems
in final best-seen, significantly above TuRPBO on at least 3, significantly below it on none,
best or tied in final cumulative on at least 12. Each is "met", "missed by k" (k short of
the bound), or, while the hybrid or TuRPBO lacks runs on some of the 18 problems, "not
judgeable" — unless the bound is out of reach already. Runs on a missing problem change no
other problem's best-or-tied count (its Holm correction is over that problem's algorithms), and
one more test in the Holm correction over problems can only raise the others' adjusted
p-values (a rejection with ``m + 1`` hypotheses is one with ``m``), so a significance against
TuRPBO can be lost but not gained elsewhere. An "at least" goal whose count plus the problems
still missing stays below its bound is therefore "missed by at least k", with the algorithms
compared so far (another algorithm added to a problem can change that problem's
correction). Checked for every label whose runs use the ``hybrid``
algorithm (the default options and configured variants alike). The fifth goal, decision time
within :data:`TIME_BOUND` times TuRPBO's at the same number of evaluations, is read from the
benchmark's records (:func:`decision_time_verdict`): ``python -m
localpbo_core.benchmarks.hybrid_compute --out docs/diagnosis/hybrid_compute_<problem>.json``
runs both algorithms side by side on the same seeds (stored seconds come from different
loads and cannot decide it); "met" when every record of the label has a whole-run ratio of at
most the bound, "missed" when one exceeds it, "not measured" without a record.
"""

from __future__ import annotations

import itertools
import json
import math
from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from localpbo_core.experiments.claims import Group
from localpbo_core.experiments.comparisons import holm, paired_wilcoxon
from localpbo_core.experiments.paper import PAPER_SEEDS

if TYPE_CHECKING:
    from localpbo_core.report import StoredRun

MAIN_PROBLEMS: tuple[tuple[str, str], ...] = (
    ("synthetic", "hartmann6"),
    ("synthetic", "rosenbrock16"),
    ("synthetic", "levy32"),
    ("synthetic", "styblinskitang64"),
    *(
        (spec, f"gp{d}_l{ls}")
        for spec in ("gp_within", "gp_out_of_model")
        for ls in ("0.1", "0.5")
        for d in (8, 16, 32)
    ),
    ("policy_warm_start", "hopper"),
    ("policy_warm_start", "walker2d"),
)
"""The paper's 18 main problems as (paper spec, problem label) (Sec. 6)."""

BEYOND_PREFIX = "beyond_"
"""Specs whose name starts with this run our additions on the main problems."""
REFERENCE = "turpbo"
"""The algorithm every other is tested against (the paper's most robust one, Sec. 6, 8)."""
HYBRID = "hybrid"
"""The registered algorithm whose labels the goal check covers."""


@dataclass(frozen=True)
class Goal:
    """A bound on one count of :class:`Standing`: ``count >= bound`` (``at_most``: ``<=``)."""

    text: str
    field: str
    bound: int
    at_most: bool = False


HYBRID_GOALS: tuple[Goal, ...] = (
    Goal("best or tied in final best-seen on at least 16 of 18", "best_final", 16),
    Goal("significantly above TuRPBO on at least 3", "above", 3),
    Goal("never significantly below TuRPBO", "below", 0, at_most=True),
    Goal("best or tied in final cumulative on at least 12 of 18", "best_cumulative", 12),
)


@dataclass(frozen=True)
class Standing:
    """One algorithm over the main problems (module docstring)."""

    algorithm: str
    run: int
    best_final: int
    best_cumulative: int
    above: int | None
    """Problems significantly above TuRPBO; None for TuRPBO itself or without shared ones."""
    below: int | None
    time_ratio: float | None
    """Geometric mean of its mean optimizer seconds over TuRPBO's; None as for ``above``."""
    problems: tuple[str, ...]
    """The problems it ran, as ``spec/label``."""


def conditions(run: StoredRun) -> str:
    """What must agree for two runs of a seed to be compared: every setting but the
    algorithm and its options (module docstring)."""
    s = run.settings
    return json.dumps(
        {
            "problem": s["problem"],
            "problem_options": s["problem_options"],
            "budget": s["budget"],
            "initial_design": s.get("initial_design"),
            "noise_fraction": s.get("noise_fraction", 0.1),
            "tie_threshold": s.get("tie_threshold", 0.0),
            "indifference": s.get("indifference", 0.0),
            "within_model": run.within_model,
        },
        sort_keys=True,
    )


def main_groups(runs: Sequence[StoredRun], alpha: float) -> list[Group]:
    """The main problems with runs of their paper spec, each a
    :class:`~localpbo_core.experiments.claims.Group` of the merged runs at the seeds
    :data:`~localpbo_core.experiments.paper.PAPER_SEEDS` (module docstring)."""
    from localpbo_core.experiments.claims import groups_of

    return [g for merged in main_runs(runs).values() for g in groups_of(merged, alpha)]


def main_runs(runs: Sequence[StoredRun]) -> dict[tuple[str, str], list[StoredRun]]:
    """The merged runs of each main problem with runs of its paper spec (module docstring),
    seen as runs of the paper spec, keyed by ``(spec, label)``."""
    seeds = set(PAPER_SEEDS)
    wanted = dict.fromkeys(label for _, label in MAIN_PROBLEMS)
    candidates = [
        r
        for r in runs
        if not r.variant
        and r.seed in seeds
        and r.problem_label in wanted
        and (r.spec.startswith(BEYOND_PREFIX) or (r.spec, r.problem_label) in MAIN_PROBLEMS)
    ]
    out: dict[tuple[str, str], list[StoredRun]] = {}
    for spec, label in MAIN_PROBLEMS:
        home = [r for r in candidates if r.spec == spec and r.problem_label == label]
        if not home:
            continue
        expected = {r.seed: conditions(r) for r in home}
        chosen: dict[str, tuple[str, list[StoredRun]]] = {}
        for r in sorted(candidates, key=lambda r: (r.spec != spec, r.spec, r.seed)):
            if r.problem_label != label or expected.get(r.seed) != conditions(r):
                continue
            source, members = chosen.setdefault(r.algorithm_label, (r.spec, []))
            if source == r.spec:
                members.append(r)
        # seen as runs of the paper spec: groups_of groups by spec and problem label
        out[(spec, label)] = [
            replace(r, spec=spec)
            for _, members in chosen.values()
            if {r.seed for r in members} == seeds
            for r in members
        ]
    return out


def same_as_reference(
    merged_runs: dict[tuple[str, str], list[StoredRun]], label: str
) -> dict[str, tuple[int, int]]:
    """Per main problem (``spec/label``) of :func:`main_runs`'s ``merged_runs`` where ``label``
    and TuRPBO both ran: how many of ``label``'s runs have TuRPBO's run's value at every
    evaluation (a hybrid that never took a local step asks TuRPBO's candidates), as
    ``(same, seeds)``."""
    out = {}
    for (spec, problem), merged in merged_runs.items():
        mine = {r.seed: r for r in merged if r.algorithm_label == label}
        theirs = {r.seed: r for r in merged if r.algorithm_label == REFERENCE}
        if not mine or not theirs:
            continue
        same = sum(
            np.array_equal(run.cumulative, theirs[seed].cumulative)
            for seed, run in mine.items()
            if seed in theirs
        )
        out[f"{spec}/{problem}"] = (same, len(mine))
    return out


def _reference_tests(groups: Sequence[Group], algorithm: str, alpha: float) -> tuple[int, int]:
    """Problems where ``algorithm`` is significantly above and below :data:`REFERENCE` in
    final best-seen (paired Wilcoxon of the two, Holm over the problems both ran)."""

    shared = [g for g in groups if g.has(algorithm, REFERENCE)]
    raw = []
    for g in shared:
        seeds = sorted(set(g.best[algorithm]) & set(g.best[REFERENCE]))
        raw.append(
            paired_wilcoxon(
                [g.best[algorithm][s] for s in seeds], [g.best[REFERENCE][s] for s in seeds]
            )
        )
    above = below = 0
    for g, p in zip(shared, holm(raw), strict=True):
        if p < alpha:
            diff = g.mean("best", algorithm) - g.mean("best", REFERENCE)
            above += diff > 0
            below += diff < 0
    return above, below


def _time_ratio(groups: Sequence[Group], algorithm: str) -> float | None:
    logs = []
    for g in groups:
        if not g.has(algorithm, REFERENCE):
            continue
        ours, theirs = g.mean("seconds", algorithm), g.mean("seconds", REFERENCE)
        if ours > 0 and theirs > 0:
            logs.append(math.log(ours / theirs))
    return math.exp(sum(logs) / len(logs)) if logs else None


def standings(groups: Sequence[Group], alpha: float) -> list[Standing]:
    """Every algorithm of ``groups`` (module docstring), in the order of the evidence rule:
    best or tied in final best-seen, then in final cumulative (both descending), then name."""
    algorithms = sorted({a for g in groups for a in g.best})
    out = []
    for a in algorithms:
        mine = [g for g in groups if a in g.best]
        best_final = sum(g.ranking("best")[1][a] for g in mine)
        best_cum = sum(g.ranking("cumulative")[1][a] for g in mine)
        shared = a != REFERENCE and any(g.has(REFERENCE) for g in mine)
        above, below = _reference_tests(groups, a, alpha) if shared else (None, None)
        out.append(
            Standing(
                a,
                len(mine),
                best_final,
                best_cum,
                above,
                below,
                _time_ratio(groups, a) if shared else None,
                tuple(g.name for g in mine),
            )
        )
    return sorted(out, key=lambda s: (-s.best_final, -s.best_cumulative, s.algorithm))


@dataclass(frozen=True)
class PairReach:
    """Two algorithms and the problems where either is best or tied (module docstring)."""

    pair: tuple[str, str]
    run: int
    """Problems either ran."""
    best_final: int
    best_cumulative: int
    neither: tuple[str, ...]
    """The problems (``spec/label``) either ran where neither is best or tied in final
    best-seen."""

    def partner(self, algorithm: str) -> str:
        """The other algorithm of the pair."""
        return self.pair[1] if self.pair[0] == algorithm else self.pair[0]


def pair_reach(groups: Sequence[Group]) -> list[PairReach]:
    """Every pair of the algorithms of ``groups`` (module docstring), most best-or-tied
    problems in final best-seen first, then in final cumulative, then by names."""
    tied: dict[tuple[str, str], set[str]] = {}
    ran: dict[str, set[str]] = {}
    for g in groups:
        for a in g.best:
            ran.setdefault(a, set()).add(g.name)
        for metric in ("best", "cumulative"):
            for a, t in g.ranking(metric)[1].items():
                members = tied.setdefault((a, metric), set())
                if t:
                    members.add(g.name)
    out = []
    for a, b in itertools.combinations(sorted(ran), 2):
        final = tied[(a, "best")] | tied[(b, "best")]
        either = ran[a] | ran[b]
        out.append(
            PairReach(
                (a, b),
                len(either),
                len(final),
                len(tied[(a, "cumulative")] | tied[(b, "cumulative")]),
                tuple(g.name for g in groups if g.name in either - final),
            )
        )
    return sorted(out, key=lambda r: (-r.best_final, -r.best_cumulative, r.pair))


def best_partners(reach: Sequence[PairReach]) -> dict[str, PairReach]:
    """Per algorithm, its first pair in ``reach`` (:func:`pair_reach`'s order), in that
    order."""
    out: dict[str, PairReach] = {}
    for r in reach:
        for a in r.pair:
            out.setdefault(a, r)
    return out


def evidence_choice(table: Sequence[Standing]) -> str | None:
    """The default by the evidence (module docstring); None when no algorithm ran on every
    main problem."""
    complete = [s for s in table if s.run == len(MAIN_PROBLEMS)]
    if not complete:
        return None
    return min(complete, key=lambda s: (-s.best_final, -s.best_cumulative, s.algorithm)).algorithm


def goal_verdicts(table: Sequence[Standing], algorithm: str) -> list[tuple[Goal, str]]:
    """Each of :data:`HYBRID_GOALS` for ``algorithm``: "met", "missed by k", "missed by at
    least k" or "not judgeable" (module docstring), with the count."""
    total = len(MAIN_PROBLEMS)
    mine = next((s for s in table if s.algorithm == algorithm), None)
    reference = next((s for s in table if s.algorithm == REFERENCE), None)
    ran = 0 if mine is None else mine.run
    reference_ran = 0 if reference is None else reference.run
    out = []
    for goal in HYBRID_GOALS:
        if mine is None or ran < total or reference_ran < total:
            why = [f"run on {ran} of {total}"]
            if reference_ran < total:
                why.append(f"TuRPBO on {reference_ran}")
            count = None if mine is None else getattr(mine, goal.field)
            if count is not None:
                why.append(f"so far {count}")
            reach = _reachable(goal, mine, reference)
            if _met_already(goal, mine):
                out.append((goal, f"met already ({', '.join(why)})"))
            elif reach is not None and reach < goal.bound:
                out.append((goal, f"missed by at least {goal.bound - reach} ({', '.join(why)})"))
            else:
                out.append((goal, f"not judgeable ({', '.join(why)})"))
            continue
        count = getattr(mine, goal.field)
        short = count - goal.bound if goal.at_most else goal.bound - count
        out.append((goal, f"met ({count})" if short <= 0 else f"missed by {short} ({count})"))
    return out


def _met_already(goal: Goal, mine: Standing | None) -> bool:
    """An "at least" goal on a best-or-tied count that ``mine`` already reaches: runs on a
    missing problem change no other problem's ranking, so the count cannot fall (the counts
    against TuRPBO can: one more problem joins their Holm correction)."""
    return (
        mine is not None
        and not goal.at_most
        and goal.field in ("best_final", "best_cumulative")
        and int(getattr(mine, goal.field)) >= goal.bound
    )


def _reachable(goal: Goal, mine: Standing | None, reference: Standing | None) -> int | None:
    """The most an "at least" goal's count can still become if ``mine`` ran, and came out
    ahead, on every main problem it (or, for the counts against TuRPBO, the pair) lacks
    (module docstring); None for an "at most" goal, which more problems can still meet."""
    if goal.at_most:
        return None
    total = len(MAIN_PROBLEMS)
    if mine is None:
        return total
    if goal.field in ("above", "below"):
        shared = set(mine.problems) & set(() if reference is None else reference.problems)
        return (getattr(mine, goal.field) or 0) + total - len(shared)
    return int(getattr(mine, goal.field)) + total - mine.run


TIME_BOUND = 2.0
"""The hybrid's decision time per run may be at most this multiple of TuRPBO's."""
DECISION_TIMES = Path(__file__).resolve().parents[2] / "docs" / "diagnosis"
"""The folder of the decision-time records (``hybrid_compute*.json``)."""


def read_decision_times(folder: Path = DECISION_TIMES) -> list[dict[str, Any]]:
    """The records ``python -m localpbo_core.benchmarks.hybrid_compute --out`` wrote into
    ``folder`` (``hybrid_compute*.json``), by file name, each with its ``file`` name."""
    out = []
    for path in sorted(folder.glob("hybrid_compute*.json")):
        doc = json.loads(path.read_text())
        doc["file"] = path.name
        out.append(doc)
    return out


def _named(name: object, options: dict[str, Any] | None, sep: str) -> str:
    """``name``, with its options (sorted, ``key=value`` joined by ``sep``) in brackets."""
    extra = sep.join(f"{k}={v}" for k, v in sorted((options or {}).items()))
    return str(name) + (f" ({extra})" if extra else "")


def _record_label(record: dict[str, Any]) -> str:
    """The label a record measured: its ``--algorithm``, with explicit options appended."""
    return _named(record["algorithm"], record.get("options"), ",")


def _record_problem(record: dict[str, Any]) -> str:
    """The problem a record measured, with its options if it names any."""
    return _named(record["problem"], record.get("problem_options"), ", ")


def decision_time_verdict(label: str, records: Sequence[dict[str, Any]]) -> str:
    """The decision-time goal for ``label`` (module docstring) from its records: "met" or
    "missed" with each problem's whole-run ratio, or "not measured"."""
    mine = [r for r in records if _record_label(r) == label]
    if not mine:
        return "not measured"
    ratios = "; ".join(f"{_record_problem(r)} {float(r['ratio']):.2f}×" for r in mine)
    worst = max(float(r["ratio"]) for r in mine)
    return f"{'met' if worst <= TIME_BOUND else 'missed'} ({ratios})"


def _local_share(record: dict[str, Any]) -> str:
    """How many of a record's hybrid asks were local steps (and probes, for records that
    count them); with neither, the hybrid asked TuRPBO's candidates throughout (the same seeds
    give the same runs)."""
    local, probes = int(record["local_asks"]), int(record.get("probe_asks", 0))
    asks = local + probes + int(record["global_asks"])
    share = f"local steps {local} of {asks} asks ({100.0 * local / max(asks, 1):.0f} %)"
    if probes:
        share += f", probes {probes} ({100.0 * probes / asks:.0f} %)"
    return share if local or probes else f"{share}: TuRPBO's candidates throughout"


def runnable(label: str) -> bool:
    """``label`` names a registered algorithm or a preset (:mod:`localpbo_core.presets`), so
    ``localpbo run --algorithm`` and ``DEFAULT_ALGORITHM`` accept it."""
    from localpbo_core.optimizers.registry import available_optimizers
    from localpbo_core.presets import available_presets

    return label in available_optimizers() or label in available_presets()


def _cell(value: int | None) -> str:
    return "—" if value is None else str(value)


def which_algorithm_section(
    runs: Sequence[StoredRun], alpha: float, decision_times: Sequence[dict[str, Any]] | None = None
) -> list[str]:
    """The results page's section "Which algorithm to run" (module docstring);
    ``decision_times``: the benchmark's records (default :func:`read_decision_times`)."""
    from localpbo_core.settings import DEFAULT_ALGORITHM

    records = read_decision_times() if decision_times is None else list(decision_times)

    groups = main_groups(runs, alpha)
    table = standings(groups, alpha)
    total = len(MAIN_PROBLEMS)
    beyond = sorted({r.spec for r in runs if r.spec.startswith(BEYOND_PREFIX)})
    lines = [
        "## Which algorithm to run",
        "",
        f"Every algorithm over the paper's {total} main problems (Sec. 6: the four synthetic "
        "functions, the GP sample paths d = 8, 16, 32 × lengthscale 0.1, 0.5 within and out "
        "of model, Hopper and Walker2d with warm start). A problem's runs are its paper spec's "
        "and those of the `beyond_*` specs run under the same conditions (problem, options, "
        "budget, initial design, noise, within-model flag); an algorithm counts on a problem "
        f"with all seeds {min(PAPER_SEEDS)}–{max(PAPER_SEEDS)}, and only those seeds "
        "are compared. Best or tied: the highest mean, or not significantly different from it "
        f"(the report's paired Wilcoxon test by seed, Holm-corrected, alpha = {alpha:g}). "
        "Above / below TuRPBO: a two-sided paired Wilcoxon test of the two in final "
        "best-seen on each problem both ran, Holm-corrected over those problems. Time: the "
        "geometric mean over the shared problems of its mean optimizer seconds per run over "
        "TuRPBO's; stored seconds come from different days and machine loads, so read it as "
        "a rough guide (`localpbo_core/experiments/beyond.py`). `beyond_*` specs with stored "
        f"runs: {', '.join(beyond) or 'none yet'}.",
        "",
        f"| algorithm | problems run (of {total}) | best or tied: final best-seen "
        "| best or tied: final cumulative | significantly above TuRPBO "
        "| significantly below TuRPBO | optimizer time / TuRPBO's |",
        "| --- | ---: | ---: | ---: | ---: | ---: | ---: |",
    ]
    for s in table:
        ratio = "—" if s.time_ratio is None else f"{s.time_ratio:.3g}×"
        lines.append(
            f"| {s.algorithm} | {s.run} | {s.best_final} | {s.best_cumulative} | "
            f"{_cell(s.above)} | {_cell(s.below)} | {ratio} |"
        )
    choice = evidence_choice(table)
    lines += [
        "",
        "**The default chosen by the evidence**: among the algorithms run on all "
        f"{total} problems, the one best or tied in final best-seen on the most; ties broken "
        "by the count in final cumulative, then by name. ",
    ]
    if choice is None:
        lines[-1] += f"No algorithm has runs on all {total} problems yet."
    else:
        pick = next(s for s in table if s.algorithm == choice)
        agree = (
            "the code's default (`DEFAULT_ALGORITHM` in `localpbo_core/settings.py`, used by "
            "`localpbo run` and the optimizer node) is the same"
            if choice == DEFAULT_ALGORITHM
            else f"the code's default (`DEFAULT_ALGORITHM`) is {DEFAULT_ALGORITHM}: they differ"
        )
        lines[-1] += (
            f"It picks **{choice}** (best or tied on {pick.best_final} of {total} in final "
            f"best-seen, {pick.best_cumulative} in final cumulative); {agree}. "
            + (
                f"`localpbo run --algorithm {choice}` runs it."
                if runnable(choice)
                else f"{choice} is neither a registered algorithm nor a preset "
                "(`localpbo_core/presets.py`): it cannot be named as a default yet."
            )
        )
    ran = {s.algorithm for s in table}
    hybrids = sorted(
        {r.algorithm_label for r in runs if r.settings.get("algorithm") == HYBRID} & ran
    ) or [HYBRID]
    time_goal = f"decision time within {TIME_BOUND:g}× of TuRPBO's at the same n (benchmark)"
    lines += [
        "",
        "**The hybrid's goal**: "
        + "; ".join(g.text for g in HYBRID_GOALS)
        + f"; {time_goal}. The counts against TuRPBO are judged only when it and TuRPBO "
        f"ran all {total} problems (their Holm corrections depend on them all). Before that, "
        'an "at least" goal is missed when its count plus the problems still missing stays '
        "below the bound, and a best-or-tied count that already reaches its bound is met: "
        "runs on a missing problem change no other problem's best-or-tied count, and one "
        "more test in a Holm correction can take a significance away but not add one. The "
        "decision time is "
        "the optimizer's seconds per run (ask and tell, episodes excluded) of both run side "
        "by side on the same seeds at 10 % noise, whole-run ratio per problem "
        "(`python -m localpbo_core.benchmarks.hybrid_compute`; stored seconds come from "
        "different loads and cannot decide it).",
        "",
        "| algorithm | " + " | ".join(g.text for g in HYBRID_GOALS) + f" | {time_goal} |",
        "| --- |" + " --- |" * (len(HYBRID_GOALS) + 1),
    ]
    for h in hybrids:
        verdicts = goal_verdicts(table, h)
        cells = [v for _, v in verdicts] + [decision_time_verdict(h, records)]
        lines.append(f"| {h} | " + " | ".join(cells) + " |")
    merged_runs = main_runs(runs)
    for h in hybrids:
        same = same_as_reference(merged_runs, h)
        if same:
            lines += [
                "",
                f"Runs of {h} with TuRPBO's value at every evaluation (the same seed; until its "
                "first local step the hybrid asks TuRPBO's candidates): "
                + "; ".join(f"{p} {k} of {n}" for p, (k, n) in same.items())
                + ".",
            ]
    partners = best_partners(pair_reach(groups))
    if partners:
        lines += [
            "",
            "**What a choice between two algorithms could reach**: a hybrid that picks one "
            "of two algorithms per problem is best or tied at most where either of them is, "
            "and only if it always picks the right one, in hindsight; a real hybrid has to "
            "tell from its own duels. So a pair's count bounds every such hybrid from above. "
            "Per algorithm, the partner with which it reaches the most (then by name):",
            "",
            f"| algorithm | partner | problems either ran (of {total}) "
            "| best or tied: final best-seen | best or tied: final cumulative "
            "| neither best or tied in final best-seen |",
            "| --- | --- | ---: | ---: | ---: | --- |",
        ]
        lines += [
            f"| {a} | {r.partner(a)} | {r.run} | {r.best_final} | {r.best_cumulative} | "
            f"{', '.join(r.neither) or '—'} |"
            for a, r in partners.items()
        ]
    measured = [r for r in records if _record_label(r) in hybrids]
    if measured:
        lines += ["", "Decision-time records (`docs/diagnosis/`):", ""]
        lines += [
            f"* `{r['command']}` (`{r['file']}`) on {r['machine']}, {r['date']}: "
            f"{float(r['turpbo_seconds_per_run']):.3g} s TuRPBO, "
            f"{float(r['hybrid_seconds_per_run']):.3g} s {_record_label(r)} per run, "
            f"{r['iterations']} evaluations after the initial design, seeds "
            f"{', '.join(str(x) for x in r['seeds'])}; {_local_share(r)};"
            for r in measured
        ]
        lines[-1] = lines[-1][:-1] + "."
    lines.append("")
    return lines


def evidence_folders(results: Path) -> list[Path]:
    """The sweep folders under ``results`` (e.g. ``docs/results``) this section reads: the
    paper specs' of :data:`MAIN_PROBLEMS` and the ``beyond_*`` specs'."""
    specs = {spec for spec, _ in MAIN_PROBLEMS}
    return [
        p
        for p in sorted(results.iterdir())
        if p.is_dir() and (p.name in specs or p.name.startswith(BEYOND_PREFIX))
    ]
