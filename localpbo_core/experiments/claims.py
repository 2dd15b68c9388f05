"""The paper's claims (Sec. 6 and App. D), each checked against stored runs by a written rule.

Every claim quotes the paper, says where it is made, and states the rule it is read as: a test
on final values (mean over seeds) or optimizer seconds. Comparative words are tested as
comparisons:

* "X performs best" / "works best": X has the highest mean (on every problem named; "partly"
  when on some, "no" when on none). Being not significantly below the best is reported beside
  it but does not make X the best.
* "tied" / "competitive" / "equivalently": not significantly different from the best by the
  report's paired Wilcoxon test with Holm correction (:func:`localpbo_core.report.compare`);
  "not significantly below Y": a two-sided paired Wilcoxon test of the two alone
  (:func:`localpbo_core.report.paired_wilcoxon`) with p >= alpha, or a higher mean.
* "most" / "especially": a count or a size compared with every other algorithm's.
* "consistently": on every problem.

A claim whose evidence is missing says "not run"; one whose evidence is partly missing is
judged on what ran and names what did not. ``localpbo report`` prints the table (claim, where,
rule, ours, holds?).

Local methods: GIPBO, GIPBOr, PrefSQP, TuRPBO; global ones: Sobol, GLISp, qEUBO, HB-EI (the
paper's split, Sec. 6); GIPBO, GIPBOr and PrefSQP are its derivative-based local methods.
"""

from __future__ import annotations

import itertools
import re
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from localpbo_core.experiments.comparisons import compare, paired_wilcoxon

if TYPE_CHECKING:
    from localpbo_core.report import StoredRun

LOCAL = ("gipbo", "gipbor", "prefsqp", "turpbo")
GLOBAL = ("sobol", "glisp", "qeubo", "hbei")
DERIVATIVE = ("gipbo", "gipbor", "prefsqp")
"""The derivative-based local methods (Sec. 6 sets TuRPBO's trust region apart from them)."""
MODEL_BASED = ("gipbo", "gipbor", "prefsqp", "turpbo", "qeubo", "hbei")
"""The algorithms with GP hyperparameters (within model: given; out of model: learned)."""
MAIN_SPECS = ("synthetic", "gp_within", "gp_out_of_model", "policy_warm_start")
"""The main experiments of Sec. 6 (ablations and experiments of our own left out)."""
_POLICY_DIMS = {"hopper": 33, "walker2d": 102}
PAPER_GP_DIMS = (8, 16, 32, 64, 96)
"""The GP dimensions of the paper's figure (Sec. 6)."""
HIGH_D_GP = 32
"""The GP dimensions read as "high-dimensional" when the highest ones are not run (the
paper's figures separate at d >= 32)."""


@dataclass(frozen=True)
class Group:
    """One problem of one spec: per algorithm, final best-seen, final cumulative and optimizer
    seconds by seed."""

    spec: str
    problem: str
    dim: int
    lengthscale: float | None
    best: dict[str, dict[int, float]]
    cumulative: dict[str, dict[int, float]]
    alpha: float
    seconds: dict[str, dict[int, float]] | None = None
    _rankings: dict[str, tuple[str, dict[str, bool]]] = field(
        default_factory=dict, compare=False, repr=False
    )
    """:meth:`ranking` per metric, computed once (the tests are the slow part)."""

    def mean(self, metric: str, algorithm: str) -> float:
        """Mean over seeds of ``metric`` (``best``, ``cumulative`` or ``seconds``)."""
        return float(np.mean(list((getattr(self, metric) or {})[algorithm].values())))

    def ranking(self, metric: str) -> tuple[str, dict[str, bool]]:
        """The best algorithm and, per algorithm, whether it is tied with it."""
        if metric not in self._rankings:
            best, _, tied = compare(getattr(self, metric), self.alpha)
            self._rankings[metric] = (best, tied)
        return self._rankings[metric]

    def has(self, *algorithms: str) -> bool:
        """All ``algorithms`` ran on this problem."""
        return all(a in self.best for a in algorithms)

    def not_below(self, metric: str, a: str, b: str) -> bool:
        """``a``'s mean above ``b``'s, or the two not significantly different (two-sided
        paired Wilcoxon by seed, p >= alpha)."""
        if self.mean(metric, a) >= self.mean(metric, b):
            return True
        values = getattr(self, metric)
        seeds = sorted(set(values[a]) & set(values[b]))
        p = paired_wilcoxon([values[a][s] for s in seeds], [values[b][s] for s in seeds])
        return p >= self.alpha

    @property
    def name(self) -> str:
        return f"{self.spec}/{self.problem}"


@dataclass(frozen=True)
class Outcome:
    """What our runs say about a claim."""

    ours: str
    holds: str  # "yes", "no", "partly" or "not run"


@dataclass(frozen=True)
class Claim:
    """A claim of the paper, where it is made, how it is checked, and the check."""

    text: str
    where: str
    reading: str
    check: Callable[[Sequence[Group]], Outcome]


def _dim(run: StoredRun) -> int:
    s = run.settings
    if s["problem"] == "gp_sample":
        return int(s["problem_options"]["dim"])
    if s["problem"] in _POLICY_DIMS:
        return _POLICY_DIMS[s["problem"]]
    match = re.search(r"(\d+)$", s["problem"])
    return int(match.group(1)) if match else 0


def groups_of(runs: Sequence[StoredRun], alpha: float) -> list[Group]:
    """Runs grouped by spec and problem label (variants are ablations: left out)."""
    out: dict[tuple[str, str], list[StoredRun]] = {}
    for r in runs:
        if not r.variant:
            out.setdefault((r.spec, r.problem_label), []).append(r)
    groups = []
    for (spec, problem), members in sorted(out.items()):
        s = members[0].settings
        ls = s["problem_options"].get("lengthscale") if s["problem"] == "gp_sample" else None
        best: dict[str, dict[int, float]] = {}
        cum: dict[str, dict[int, float]] = {}
        secs: dict[str, dict[int, float]] = {}
        for r in members:
            best.setdefault(r.algorithm_label, {})[r.seed] = float(r.best_seen[-1])
            cum.setdefault(r.algorithm_label, {})[r.seed] = float(r.cumulative[-1])
            secs.setdefault(r.algorithm_label, {})[r.seed] = float(r.optimizer_seconds)
        groups.append(
            Group(
                spec,
                problem,
                _dim(members[0]),
                None if ls is None else float(ls),
                best,
                cum,
                alpha,
                secs,
            )
        )
    return groups


def _find(groups: Sequence[Group], spec: str, problem: str) -> Group | None:
    return next((g for g in groups if g.spec == spec and g.problem == problem), None)


def _verdict(ok: int, total: int) -> str:
    if total == 0:
        return "not run"
    return "yes" if ok == total else ("no" if ok == 0 else "partly")


def _best_mean(g: Group, metric: str) -> str:
    return g.ranking(metric)[0]


def _fmt(x: float) -> str:
    return f"{x:.4g}"


def _missing_gp_dims(gp: Sequence[Group]) -> str:
    missing = [d for d in PAPER_GP_DIMS if not any(g.dim == d for g in gp)]
    return f" (GP paths d = {', '.join(map(str, missing))} not run)" if missing else ""


# ---------------------------------------------------------------------- Sec. 6, GP paths
def _short_lengthscale_top(groups: Sequence[Group]) -> tuple[list[Group], str]:
    """The ℓ = 0.1 GP groups (main specs) at the highest d run, and a note on what is
    missing; empty if that d is below :data:`HIGH_D_GP`."""
    gp = [g for g in groups if g.spec in ("gp_within", "gp_out_of_model")]
    short = [g for g in gp if g.lengthscale == 0.1]
    if not short:
        return [], "no GP runs with lengthscale 0.1"
    top = max(g.dim for g in short)
    note = _missing_gp_dims(gp)
    if top < HIGH_D_GP:
        return [], f"highest d run: {top}{note}"
    return [g for g in short if g.dim == top], note


def _local_excel_short_lengthscale(groups: Sequence[Group]) -> Outcome:
    at_top, note = _short_lengthscale_top(groups)
    if not at_top:
        return Outcome(note, "not run")
    parts = [f"{g.spec} d = {g.dim}: best {_best_mean(g, 'best')}" for g in at_top]
    ok = sum(_best_mean(g, "best") in LOCAL for g in at_top)
    return Outcome("; ".join(parts) + note, _verdict(ok, len(at_top)))


def _prefsqp_short_lengthscale(groups: Sequence[Group]) -> Outcome:
    at_top, note = _short_lengthscale_top(groups)
    at_top = [g for g in at_top if g.has("prefsqp")]
    if not at_top:
        return Outcome(note or "PrefSQP not run", "not run")
    parts, ok = [], 0
    for g in at_top:
        best, tied = g.ranking("best")
        ok += tied["prefsqp"]
        rank = sorted(g.best, key=lambda a: -g.mean("best", a)).index("prefsqp") + 1
        state = "best" if best == "prefsqp" else ("tied" if tied["prefsqp"] else "below")
        parts.append(f"{g.spec} d = {g.dim}: PrefSQP {state} (rank {rank} of {len(g.best)})")
    return Outcome("; ".join(parts) + note, _verdict(ok, len(at_top)))


def _robust_counts(groups: Sequence[Group]) -> tuple[dict[str, int], dict[str, int]]:
    """Per algorithm of the main specs: problems where it is best or tied with the best, and
    of those, the ones TuRPBO also ran; plus per algorithm TuRPBO's count on the same ones."""
    main = [g for g in groups if g.spec in MAIN_SPECS and len(g.best) > 1]
    theirs: dict[str, int] = {}
    turpbo: dict[str, int] = {}
    for g in main:
        if not g.has("turpbo"):
            continue
        _, tied = g.ranking("best")
        for a in g.best:
            if a == "turpbo":
                continue
            theirs[a] = theirs.get(a, 0) + tied[a]
            turpbo[a] = turpbo.get(a, 0) + tied["turpbo"]
    return theirs, turpbo


def _turpbo_most_robust(groups: Sequence[Group]) -> Outcome:
    main = [g for g in groups if g.spec in MAIN_SPECS and len(g.best) > 1 and g.has("turpbo")]
    if not main:
        return Outcome("TuRPBO not run", "not run")
    ok = sum(g.ranking("best")[1]["turpbo"] for g in main)
    theirs, turpbo = _robust_counts(groups)
    ahead = sorted(a for a in theirs if theirs[a] > turpbo[a])
    parts = [f"TuRPBO best or tied on {ok} of {len(main)} problems"]
    for a in sorted(theirs, key=lambda a: (-theirs[a], a)):
        shared = sum(1 for g in main if a in g.best)
        parts.append(f"{a} {theirs[a]} of {shared} (TuRPBO {turpbo[a]})")
    holds = "no" if ahead else "yes"
    return Outcome(", ".join(parts[:1]) + "; " + ", ".join(parts[1:]), holds)


def _smooth_groups(groups: Sequence[Group], *algorithms: str) -> list[Group]:
    return [
        g
        for g in groups
        if g.spec in ("gp_within", "gp_out_of_model")
        and g.lengthscale == 0.5
        and any(a in g.best for a in algorithms)
    ]


def _trapped_on_smooth(groups: Sequence[Group]) -> Outcome:
    found = [g for g in _smooth_groups(groups, *DERIVATIVE) if any(a in g.best for a in GLOBAL)]
    if not found:
        return Outcome("no ℓ = 0.5 GP runs", "not run")
    parts, ok = [], 0
    for g in found:
        top_global = max((a for a in GLOBAL if a in g.best), key=lambda a: g.mean("best", a))
        beaten = [a for a in DERIVATIVE if a in g.best]
        below = [a for a in beaten if g.mean("best", a) < g.mean("best", top_global)]
        ok += len(below) == len(beaten)
        parts.append(f"{g.spec} d = {g.dim}: {top_global} above {len(below)} of {len(beaten)}")
    return Outcome("; ".join(parts), _verdict(ok, len(found)))


def _turpbo_escapes(groups: Sequence[Group]) -> Outcome:
    found = [g for g in _smooth_groups(groups, "turpbo") if g.has("turpbo")]
    if not found:
        return Outcome("no ℓ = 0.5 GP runs of TuRPBO", "not run")
    parts, ok = [], 0
    for g in found:
        others = [a for a in DERIVATIVE if a in g.best]
        below = [a for a in others if g.mean("best", a) < g.mean("best", "turpbo")]
        ok += len(below) == len(others)
        parts.append(f"{g.spec} d = {g.dim}: above {len(below)} of {len(others)}")
    return Outcome("; ".join(parts), _verdict(ok, len(found)))


def _gp_pairs(groups: Sequence[Group], *algorithms: str) -> list[tuple[Group, Group]]:
    """(within, out-of-model) groups of the same GP problem where both ran ``algorithms``."""
    pairs = []
    for w in groups:
        if w.spec != "gp_within" or not w.has(*algorithms):
            continue
        o = _find(groups, "gp_out_of_model", w.problem)
        if o is not None and o.has(*algorithms):
            pairs.append((w, o))
    return pairs


def _drops(groups: Sequence[Group]) -> dict[str, tuple[float, int, int]]:
    """Per model-based algorithm run in both settings: the mean drop of its mean final
    best-seen from within to out of model, the pairs where it is lower out of model, and the
    pairs."""
    out = {}
    for a in MODEL_BASED:
        pairs = _gp_pairs(groups, a)
        if pairs:
            drops = [w.mean("best", a) - o.mean("best", a) for w, o in pairs]
            out[a] = (float(np.mean(drops)), sum(d > 0 for d in drops), len(pairs))
    return out


def _degrade_most(groups: Sequence[Group], named: Sequence[str]) -> Outcome:
    """Each of ``named`` loses more from within to out of model (mean drop > 0) than every
    other model-based algorithm run in both settings."""
    drops = _drops(groups)
    if not all(a in drops for a in named) or len(drops) <= len(named):
        return Outcome("not run in both settings", "not run")
    others = [a for a in drops if a not in named]
    ok = sum(drops[a][0] > 0 and all(drops[a][0] > drops[b][0] for b in others) for a in named)
    ranked = sorted(drops, key=lambda a: (-drops[a][0], a))
    parts = [f"{a} {drops[a][0]:.3g} (lower on {drops[a][1]} of {drops[a][2]})" for a in ranked]
    return Outcome("mean drop within → out of model: " + ", ".join(parts), _verdict(ok, len(named)))


def _qeubo_gipbo_sensitive(groups: Sequence[Group]) -> Outcome:
    return _degrade_most(groups, ("qeubo", "gipbo"))


# ---------------------------------------------------------------------- Sec. 6, synthetic
def _synthetic(groups: Sequence[Group]) -> list[Group]:
    return sorted((g for g in groups if g.spec == "synthetic"), key=lambda g: g.dim)


def _local_more_useful_high_d(groups: Sequence[Group]) -> Outcome:
    found = _synthetic(groups)
    high = [g for g in found if g.dim >= 32]
    if not high:
        return Outcome("no synthetic problem with d >= 32 run", "not run")
    parts = [f"{g.problem}: best {_best_mean(g, 'best')}" for g in found]
    ok = sum(_best_mean(g, "best") in LOCAL for g in high)
    return Outcome("; ".join(parts), _verdict(ok, len(high)))


def _local_cumulative_high_d(groups: Sequence[Group]) -> Outcome:
    synth = [g for g in _synthetic(groups) if g.dim >= 32]
    parts, ok = [], 0
    for g in synth:
        best = _best_mean(g, "cumulative")
        ok += best in LOCAL
        parts.append(f"{g.problem}: best cumulative {best}")
    return Outcome(
        "; ".join(parts) or "Levy 32 / Styblinski-Tang 64 not run", _verdict(ok, len(synth))
    )


def _prefsqp_beats_gipbo(groups: Sequence[Group]) -> Outcome:
    both = [
        g
        for g in groups
        if g.spec in ("synthetic", "gp_within", "gp_out_of_model") and g.has("prefsqp", "gipbo")
    ]
    wins = [g for g in both if g.mean("best", "prefsqp") > g.mean("best", "gipbo")]
    losses = sorted(g.name for g in both if g not in wins)
    ours = f"PrefSQP ahead on {len(wins)} of {len(both)} problems"
    if losses:
        ours += f"; behind on {', '.join(losses)}"
    return Outcome(ours, _verdict(len(wins), len(both)))


def _prefsqp_competitive_turpbo(groups: Sequence[Group]) -> Outcome:
    both = [g for g in _synthetic(groups) if g.has("prefsqp", "turpbo")]
    if not both:
        return Outcome("PrefSQP and TuRPBO not both run", "not run")
    ok = [g for g in both if g.not_below("best", "prefsqp", "turpbo")]
    below = [g.problem for g in both if g not in ok]
    ours = f"not significantly below TuRPBO on {len(ok)} of {len(both)}"
    if below:
        ours += f"; below on {', '.join(below)}"
    return Outcome(ours, "yes" if 2 * len(ok) > len(both) else "no")


def _prefsqp_beats_turpbo_at_highest_d(groups: Sequence[Group]) -> Outcome:
    settings: list[Group] = []
    notes = []
    synth = [g for g in _synthetic(groups) if g.has("prefsqp", "turpbo")]
    if synth:
        settings.append(max(synth, key=lambda g: g.dim))
    gp = [
        g
        for g in groups
        if g.spec in ("gp_within", "gp_out_of_model") and g.has("prefsqp", "turpbo")
    ]
    top_gp = max(PAPER_GP_DIMS)
    settings += [g for g in gp if g.dim == top_gp]
    if not any(g.dim == top_gp for g in gp):
        notes.append(f"GP paths d = {top_gp} not run")
    if not settings:
        return Outcome("; ".join(notes) or "not run", "not run")
    wins = [g for g in settings if g.mean("best", "prefsqp") > g.mean("best", "turpbo")]
    parts = [
        f"{g.name}: PrefSQP {_fmt(g.mean('best', 'prefsqp'))}, TuRPBO "
        f"{_fmt(g.mean('best', 'turpbo'))}"
        for g in settings
    ]
    return Outcome("; ".join(parts + notes), _verdict(len(wins), len(settings)))


def _turpbo_best_on_hartmann(groups: Sequence[Group]) -> Outcome:
    g = _find(groups, "synthetic", "hartmann6")
    if g is None or not g.has("turpbo"):
        return Outcome("Hartmann 6 not run", "not run")
    best, tied = g.ranking("best")
    ours = (
        f"best mean: {best} ({_fmt(g.mean('best', best))}); TuRPBO {_fmt(g.mean('best', 'turpbo'))}"
    )
    if best != "turpbo":
        ours += ", not significantly below it" if tied["turpbo"] else ", significantly below it"
    return Outcome(ours, "yes" if best == "turpbo" else "no")


CHEAP = ("sobol", "glisp")
COSTLY = ("hbei", "gipbo")
SCALABLE = ("qeubo", "prefsqp", "turpbo")


def _cheap(groups: Sequence[Group]) -> Outcome:
    found = [g for g in _synthetic(groups) if g.has(*CHEAP) and any(a in g.best for a in COSTLY)]
    if not found:
        return Outcome(
            "Sobol, GLISp, HB-EI and GIPBO not run on the synthetic benchmarks", "not run"
        )
    parts, ok = [], 0
    for g in found:
        costly = [a for a in COSTLY if a in g.best]
        cheapest_costly = min(g.mean("seconds", a) for a in costly)
        top = max(g.mean("seconds", a) for a in CHEAP)
        ok += top < cheapest_costly
        parts.append(
            f"{g.problem}: Sobol {_fmt(g.mean('seconds', 'sobol'))} s, GLISp "
            f"{_fmt(g.mean('seconds', 'glisp'))} s; "
            + ", ".join(f"{a} {_fmt(g.mean('seconds', a))} s" for a in costly)
        )
    return Outcome("; ".join(parts), _verdict(ok, len(found)))


def _costly(groups: Sequence[Group]) -> Outcome:
    found = [g for g in _synthetic(groups) if g.has(*COSTLY)]
    if not found:
        return Outcome("HB-EI and GIPBO not run on the synthetic benchmarks", "not run")
    parts, ok = [], 0
    for a in COSTLY:
        series = [g.mean("seconds", a) for g in found]
        rising = all(y > x for x, y in itertools.pairwise(series))
        ok += rising
        parts.append(
            f"{a}: "
            + ", ".join(f"{_fmt(s)} s" for s in series)
            + ("" if rising else " (not rising)")
        )
    top = found[-1]
    order = sorted(top.best, key=lambda a: -top.mean("seconds", a))
    highest = set(order[:2]) == set(COSTLY)
    parts.append(f"the two highest at {top.problem}: {', '.join(order[:2])}")
    return Outcome("; ".join(parts), _verdict(ok + highest, len(COSTLY) + 1))


def _feasible(groups: Sequence[Group]) -> Outcome:
    from localpbo_core.experiments.paper import paper_seconds

    top = max(_synthetic(groups), key=lambda g: g.dim, default=None)
    if top is None or top.dim < 64:
        return Outcome("Styblinski-Tang 64 not run", "not run")
    parts, ok = [], 0
    for a in SCALABLE:
        theirs = paper_seconds(top.problem, a)
        if a not in top.best or theirs is None:
            parts.append(f"{a}: not run")
            continue
        s = top.mean("seconds", a)
        ok += s <= theirs
        parts.append(f"{a} {_fmt(s)} s (paper {theirs:g} s)")
    return Outcome(f"{top.problem}: {', '.join(parts)}", _verdict(ok, len(SCALABLE)))


# ---------------------------------------------------------------------- Sec. 6, policy search
def _policy(groups: Sequence[Group], spec: str, *having: str) -> list[Group]:
    """The groups of ``spec``'s policy tasks, those on which every one of ``having`` ran."""
    return [g for g in (_find(groups, spec, t) for t in _POLICY_DIMS) if g and g.has(*having)]


_PAPER_POLICY_ALGORITHMS = {
    "hopper": ("sobol", "glisp", "qeubo", "hbei", "prefsqp", "gipbor", "gipbo", "turpbo"),
    "walker2d": ("sobol", "glisp", "qeubo", "prefsqp", "gipbor", "turpbo"),
}
"""The algorithms of the paper's policy table (App. D.6) per task."""


def _missing_policy(g: Group) -> str:
    missing = [a for a in _PAPER_POLICY_ALGORITHMS[g.problem] if a not in g.best]
    return f" ({', '.join(missing)} not run)" if missing else ""


def _turpbo_best_policy(groups: Sequence[Group]) -> Outcome:
    tasks = _policy(groups, "policy_warm_start", "turpbo")
    if not tasks:
        return Outcome("policy search with warm start not run", "not run")
    parts, ok = [], 0
    for g in tasks:
        best = _best_mean(g, "best")
        ok += best == "turpbo"
        parts.append(f"{g.problem}: best {best}{_missing_policy(g)}")
    missing = "" if len(tasks) == 2 else " (one task not run)"
    return Outcome("; ".join(parts) + missing, _verdict(ok, len(tasks)))


def _local_cumulative_policy(groups: Sequence[Group]) -> Outcome:
    parts, ok, total = [], 0, 0
    for g in _policy(groups, "policy_warm_start"):
        loc = [a for a in LOCAL if a in g.cumulative]
        glo = [a for a in GLOBAL if a in g.cumulative]
        if not loc or not glo:
            continue
        total += 1
        worst_local = min(g.mean("cumulative", a) for a in loc)
        best_global = max(g.mean("cumulative", a) for a in glo)
        ok += worst_local > best_global
        parts.append(
            f"{g.problem}: worst local {_fmt(worst_local)}, best global {_fmt(best_global)}"
            + _missing_policy(g)
        )
    return Outcome("; ".join(parts) or "not run", _verdict(ok, total))


def _glisp_policy(groups: Sequence[Group]) -> Outcome:
    tasks = [
        g
        for g in _policy(groups, "policy_warm_start")
        if g.has("glisp") and any(a in g.best for a in LOCAL)
    ]
    parts, ok = [], 0
    for g in tasks:
        _, tied = g.ranking("best")
        below = all(
            g.mean("cumulative", "glisp") < g.mean("cumulative", a) for a in LOCAL if a in g.best
        )
        ok += tied["glisp"] and below
        parts.append(
            f"{g.problem}: final {'tied with' if tied['glisp'] else 'below'} the best, "
            f"cumulative {'below' if below else 'not below'} every local method"
        )
    missing = [t for t in _POLICY_DIMS if t not in {g.problem for g in tasks}]
    if missing and tasks:
        parts.append(f"{', '.join(missing)}: GLISp not run")
    return Outcome("; ".join(parts) or "GLISp not run on policy search", _verdict(ok, len(tasks)))


def _no_warm_start_pairs(groups: Sequence[Group]) -> list[tuple[Group, Group]]:
    pairs = []
    for cold in _policy(groups, "policy_no_warm_start"):
        warm = _find(groups, "policy_warm_start", cold.problem)
        if warm is not None:
            pairs.append((warm, cold))
    return pairs


def _cold_missing(groups: Sequence[Group], needed: Sequence[str]) -> list[str]:
    """What a claim on policy search without warm start lacks: per task, the task itself when
    none of its runs are stored, else those of ``needed`` that the paper ran there
    (:data:`_PAPER_POLICY_ALGORITHMS`) and that have no complete group."""
    out = []
    for task in _POLICY_DIMS:
        cold = _find(groups, "policy_no_warm_start", task)
        if cold is None:
            out.append(task)
            continue
        absent = [a for a in needed if a in _PAPER_POLICY_ALGORITHMS[task] and a not in cold.best]
        if absent:
            out.append(f"{task}: {', '.join(absent)}")
    return out


def _cold_tally(
    groups: Sequence[Group], judged: Sequence[tuple[int, int, str]], needed: Sequence[str]
) -> Outcome:
    """The outcome of a claim on policy search without warm start from each task's (holds, out
    of, note): the notes joined, the counts summed into the verdict. A claim about both tasks
    and the algorithms ``needed`` holds ("yes") only when all of them ran: while some did not
    (:func:`_cold_missing`, named in the note), agreement on what ran is "partly"."""
    missing = _cold_missing(groups, needed)
    if not judged:
        return Outcome("policy search without warm start not run", "not run")
    ok = sum(holds for holds, _, _ in judged)
    total = sum(out_of for _, out_of, _ in judged)
    verdict = _verdict(ok, total)
    notes = [note for _, _, note in judged]
    if missing:
        notes.append(f"not run: {'; '.join(missing)}")
        if verdict == "yes":
            verdict = "partly"
    return Outcome("; ".join(notes), verdict)


def _local_less_reliable_cold(groups: Sequence[Group]) -> Outcome:
    judged = []
    for warm, cold in _no_warm_start_pairs(groups):
        both = [a for a in LOCAL if a in warm.best and a in cold.best]
        lower = [a for a in both if cold.mean("best", a) < warm.mean("best", a)]
        note = f"{cold.problem}: lower without warm start {len(lower)} of {len(both)}"
        judged.append((len(lower), len(both), note))
    return _cold_tally(groups, judged, LOCAL)


def _gradient_below_random_cold(groups: Sequence[Group]) -> Outcome:
    judged = []
    for warm, cold in _no_warm_start_pairs(groups):
        if not cold.has("sobol"):
            continue
        both = [a for a in DERIVATIVE if a in warm.best and a in cold.best]
        worse = [
            a
            for a in both
            if cold.mean("best", a) < warm.mean("best", a)
            and cold.mean("best", a) < cold.mean("best", "sobol")
        ]
        note = f"{cold.problem}: degraded and below Sobol {len(worse)} of {len(both)}"
        judged.append((len(worse), len(both), note))
    return _cold_tally(groups, judged, (*DERIVATIVE, "sobol"))


def _gradient_cumulative_vs_glisp_cold(groups: Sequence[Group]) -> Outcome:
    judged = []
    for g in _policy(groups, "policy_no_warm_start", "glisp"):
        mine = [a for a in DERIVATIVE if a in g.best]
        good = [
            a
            for a in mine
            if g.not_below("cumulative", a, "glisp") and g.mean("best", "glisp") > g.mean("best", a)
        ]
        judged.append((len(good), len(mine), f"{g.problem}: {len(good)} of {len(mine)}"))
    return _cold_tally(groups, judged, (*DERIVATIVE, "glisp"))


def _turpbo_cold(groups: Sequence[Group]) -> Outcome:
    judged = []
    for g in _policy(groups, "policy_no_warm_start", "turpbo"):
        _, tied = g.ranking("best")
        note = f"{g.problem}: {'tied with the best' if tied['turpbo'] else 'below'}"
        judged.append((tied["turpbo"], 1, note))
        if g.problem == "hopper" and g.has("sobol"):
            not_better = g.not_below("best", "sobol", "turpbo")
            judged.append((not_better, 1, f"hopper: {'not ' if not_better else ''}above Sobol"))
    return _cold_tally(groups, judged, ("turpbo", "sobol"))


# ---------------------------------------------------------------------- App. D.4
def _gipbor_below_gipbo_low_d(groups: Sequence[Group]) -> Outcome:
    gp = [
        g for g in groups if g.spec in ("gp_within", "gp_out_of_model") and g.has("gipbo", "gipbor")
    ]
    low = [g for g in gp if g.dim in (8, 16)]
    if not low:
        return Outcome("GIPBO and GIPBOr not run at d = 8, 16", "not run")
    below = [g for g in low if g.mean("best", "gipbor") < g.mean("best", "gipbo")]
    gaps = {
        ls: [g.mean("best", "gipbo") - g.mean("best", "gipbor") for g in low if g.lengthscale == ls]
        for ls in (0.1, 0.5)
    }
    especially = bool(gaps[0.1] and gaps[0.5]) and np.mean(gaps[0.1]) > np.mean(gaps[0.5])
    ours = f"below on {len(below)} of {len(low)}; mean gap " + ", ".join(
        f"ℓ = {ls:g}: {np.mean(v):.3g}" for ls, v in gaps.items() if v
    )
    holds = _verdict(len(below), len(low))
    if holds == "yes" and not especially:
        holds = "partly"
    return Outcome(ours, holds)


def _gipbor_gap_vanishes_32(groups: Sequence[Group]) -> Outcome:
    gp = [
        g for g in groups if g.spec in ("gp_within", "gp_out_of_model") and g.has("gipbo", "gipbor")
    ]
    at32 = [g for g in gp if g.dim == 32]
    if not at32:
        return Outcome("GIPBO and GIPBOr not run at d = 32", "not run")
    parts, ok = [], 0
    for g in at32:
        low = [
            h.mean("best", "gipbo") - h.mean("best", "gipbor")
            for h in gp
            if h.spec == g.spec and h.lengthscale == g.lengthscale and h.dim in (8, 16)
        ]
        gap = g.mean("best", "gipbo") - g.mean("best", "gipbor")
        tied = g.not_below("best", "gipbor", "gipbo")
        smaller = bool(low) and gap < float(np.mean(low))
        ok += tied and smaller
        parts.append(
            f"{g.name}: gap {gap:.3g}"
            + (f" (d = 8, 16: {np.mean(low):.3g})" if low else "")
            + ("" if tied else ", GIPBOr significantly below")
        )
    return Outcome("; ".join(parts), _verdict(ok, len(at32)))


def _gipbo_degrades_out_of_model(groups: Sequence[Group]) -> Outcome:
    return _degrade_most(groups, ("gipbo", "gipbor"))


def _hbei_competitive_within(groups: Sequence[Group]) -> Outcome:
    short = [g for g in groups if g.spec == "gp_within" and g.lengthscale == 0.1 and g.has("hbei")]
    parts, ok = [], 0
    for g in sorted(short, key=lambda g: g.dim):
        best, tied = g.ranking("best")
        ok += tied["hbei"]
        parts.append(f"d = {g.dim}: {'tied with' if tied['hbei'] else 'below'} {best}")
    return Outcome("; ".join(parts) or "HB-EI not run within model", _verdict(ok, len(short)))


# ---------------------------------------------------------------------- App. D.7
ABLATION_SYNTHETIC = ("levy32", "styblinskitang32")
ABLATION_GP = ("gp32_l0.1", "gp32_l0.5")
PREFSQP_ABLATION = "ablation_prefsqp_line_search"
TURPBO_ABLATION = "ablation_turpbo_acquisition"
QEUBO_ABLATION = "ablation_qeubo_batch"
QEUBO_VARIANTS = ("qeubo_q1", "qeubo_q2", "qeubo_q4")


def _ablation(groups: Sequence[Group], spec: str, problems: Sequence[str]) -> list[Group]:
    """The groups of ablation ``spec`` on ``problems`` (out of model, d = 32) that ran."""
    return [g for g in (_find(groups, spec, p) for p in problems) if g is not None]


def _all_tied(groups: Sequence[Group], spec: str, problems: Sequence[str]) -> Outcome:
    """Every variant tied with the best (final best-seen) on each of ``problems``."""
    found = _ablation(groups, spec, problems)
    parts, ok = [], 0
    for g in found:
        best, tied = g.ranking("best")
        apart = sorted(a for a, t in tied.items() if not t)
        ok += not apart
        parts.append(
            f"{g.problem}: best {best}"
            + (f", below it {', '.join(apart)}" if apart else ", all tied")
        )
    return Outcome("; ".join(parts) or f"{spec} not run", _verdict(ok, len(found)))


def _best_variant(
    groups: Sequence[Group], spec: str, problems: Sequence[str], variant: str
) -> Outcome:
    """``variant`` has the highest mean final best-seen on each of ``problems``."""
    found = [g for g in _ablation(groups, spec, problems) if variant in g.best]
    if not found:
        return Outcome(f"{spec} not run", "not run")
    parts, best_on = [], 0
    for g in found:
        best, tied = g.ranking("best")
        best_on += best == variant
        if best == variant:
            parts.append(f"{g.problem}: best {best}")
            continue
        rank = sorted(g.best, key=lambda a: -g.mean("best", a)).index(variant) + 1
        state = "not significantly below" if tied[variant] else "significantly below"
        parts.append(f"{g.problem}: best {best}; {variant} rank {rank} of {len(g.best)}, {state}")
    return Outcome("; ".join(parts), _verdict(best_on, len(found)))


def _prefsqp_variants_synthetic(groups: Sequence[Group]) -> Outcome:
    return _all_tied(groups, PREFSQP_ABLATION, ABLATION_SYNTHETIC)


def _prefsqp_full_step_gp(groups: Sequence[Group]) -> Outcome:
    return _best_variant(groups, PREFSQP_ABLATION, ABLATION_GP, "prefsqp_full")


def _turpbo_ts_gp(groups: Sequence[Group]) -> Outcome:
    return _best_variant(groups, TURPBO_ABLATION, ABLATION_GP, "turpbo_ts")


def _turpbo_qeubo_synthetic(groups: Sequence[Group]) -> Outcome:
    found = [
        g for g in _ablation(groups, TURPBO_ABLATION, ABLATION_SYNTHETIC) if g.has("turpbo_qeubo")
    ]
    parts, ok = [], 0
    for g in found:
        best, tied = g.ranking("best")
        ok += tied["turpbo_qeubo"]
        parts.append(
            f"{g.problem}: best {best}, turpbo_qeubo {'tied' if tied['turpbo_qeubo'] else 'below'}"
        )
    return Outcome("; ".join(parts) or f"{TURPBO_ABLATION} not run", _verdict(ok, len(found)))


def _qeubo_batches_equal(groups: Sequence[Group]) -> Outcome:
    return _all_tied(groups, QEUBO_ABLATION, ABLATION_GP + ABLATION_SYNTHETIC)


_LOCAL_AT_32 = {
    "gp32_l0.1": ("gp_out_of_model", LOCAL),
    "gp32_l0.5": ("gp_out_of_model", LOCAL),
    "levy32": ("synthetic", LOCAL),
    "styblinskitang32": (PREFSQP_ABLATION, ("prefsqp_thompson",)),
}
"""Where the local methods' runs on each problem of the qEUBO ablation are: the main specs
(out of model), and for Styblinski-Tang 32, which no main spec has, the ablations' default
variants (PrefSQP with its Thompson line search; TuRPBO's Thompson sampling below)."""


def _qeubo_below_local_32(groups: Sequence[Group]) -> Outcome:
    found = _ablation(groups, QEUBO_ABLATION, ABLATION_GP + ABLATION_SYNTHETIC)
    if not found:
        return Outcome(f"{QEUBO_ABLATION} not run", "not run")
    parts, ok, total = [], 0, 0
    for g in found:
        spec, labels = _LOCAL_AT_32[g.problem]
        locals_: list[tuple[str, float]] = []
        home = _find(groups, spec, g.problem)
        if home is not None:
            locals_ += [(a, home.mean("best", a)) for a in labels if a in home.best]
        if g.problem == "styblinskitang32":
            turpbo = _find(groups, TURPBO_ABLATION, g.problem)
            if turpbo is not None and "turpbo_ts" in turpbo.best:
                locals_.append(("turpbo_ts", turpbo.mean("best", "turpbo_ts")))
        if not locals_:
            continue
        total += 1
        top_q = max(g.mean("best", a) for a in g.best)
        worst_local = min(locals_, key=lambda t: t[1])
        ok += top_q < worst_local[1]
        above = sorted(a for a, v in locals_ if v <= top_q)
        parts.append(
            f"{g.problem}: best qEUBO {_fmt(top_q)}, lowest local {worst_local[0]} "
            f"{_fmt(worst_local[1])}" + (f" (qEUBO not below {', '.join(above)})" if above else "")
        )
    return Outcome("; ".join(parts) or "local methods not run there", _verdict(ok, total))


CLAIMS: tuple[Claim, ...] = (
    # Sec. 6, GP sample paths
    Claim(
        "Local methods excel in high-dimensional, short-lengthscale problems",
        "Sec. 6, GP sample paths",
        f"lengthscale 0.1 at the highest d run (at least {HIGH_D_GP}; the paper's go to 96), "
        "within and out of model: the highest mean final best-seen is a local method's",
        _local_excel_short_lengthscale,
    ),
    Claim(
        "PrefSQP performs particularly well here",
        "Sec. 6, GP sample paths",
        "the same problems: PrefSQP has the highest mean final best-seen or is not "
        "significantly below it",
        _prefsqp_short_lengthscale,
    ),
    Claim(
        "TuRPBO is the most robust overall",
        "Sec. 6, GP sample paths; Sec. 8",
        "main experiments (synthetic, GP paths within and out of model, policy search with "
        "warm start): TuRPBO is best or tied with the best (final best-seen) on at least as "
        "many problems as every other algorithm, counted on the problems both ran",
        _turpbo_most_robust,
    ),
    Claim(
        "For very smooth functions, locality is less beneficial, and with only two initial "
        "points, local methods can get trapped in poor local optima and underperform global "
        "baselines",
        "Sec. 6, GP sample paths",
        "lengthscale 0.5 paths, within and out of model: the best global method's mean final "
        "best-seen above each derivative-based local method's (GIPBO, GIPBOr, PrefSQP)",
        _trapped_on_smooth,
    ),
    Claim(
        "Contrary to the derivative-based local PBO approaches, the wide initial trust region "
        "of TuRPBO allows it to escape a bad initialization",
        "Sec. 6, GP sample paths",
        "lengthscale 0.5 paths: TuRPBO's mean final best-seen above GIPBO's, GIPBOr's and "
        "PrefSQP's",
        _turpbo_escapes,
    ),
    Claim(
        "The out-of-model comparison further reveals that qEUBO and GIPBO are sensitive to "
        "hyperparameter learning",
        "Sec. 6, GP sample paths",
        "GP paths run in both settings: each of qEUBO and GIPBO loses more mean final "
        "best-seen from within to out of model (averaged over the paths) than every other "
        "model-based algorithm (GIPBOr, PrefSQP, TuRPBO, HB-EI)",
        _qeubo_gipbo_sensitive,
    ),
    # Sec. 6, standard benchmarks
    Claim(
        "local methods become more useful as dimensionality and landscape complexity increase",
        "Sec. 6, synthetic benchmarks",
        "synthetic problems with d >= 32 (Levy 32, Styblinski-Tang 64): the highest mean "
        "final best-seen is a local method's",
        _local_more_useful_high_d,
    ),
    Claim(
        "Our local PBO methods achieve higher cumulative performance in high-dimensional settings",
        "Sec. 6, synthetic benchmarks (figure caption)",
        "Levy 32 and Styblinski-Tang 64: the highest mean final cumulative is a local method's",
        _local_cumulative_high_d,
    ),
    Claim(
        "PrefSQP consistently outperforms GIPBO",
        "Sec. 6, synthetic benchmarks",
        "PrefSQP's mean final best-seen above GIPBO's on every synthetic and GP problem both ran",
        _prefsqp_beats_gipbo,
    ),
    Claim(
        "[PrefSQP] is mostly competitive with TuRPBO",
        "Sec. 6, synthetic benchmarks",
        "synthetic problems: PrefSQP not significantly below TuRPBO (final best-seen; paired "
        "Wilcoxon of the two) on more than half",
        _prefsqp_competitive_turpbo,
    ),
    Claim(
        "[PrefSQP is] outperforming [TuRPBO] in the highest-dimensional setting",
        "Sec. 6, synthetic benchmarks",
        "Styblinski-Tang 64 and the GP paths with d = 96, within and out of model: PrefSQP's "
        "mean final best-seen above TuRPBO's",
        _prefsqp_beats_turpbo_at_highest_d,
    ),
    Claim(
        "The main exception is Hartmann, where TuRPBO performs best",
        "Sec. 6, synthetic benchmarks",
        "Hartmann 6: TuRPBO has the highest mean final best-seen",
        _turpbo_best_on_hartmann,
    ),
    Claim(
        "Sobol and GLISp are inexpensive",
        "Sec. 6, compute time",
        "every synthetic problem: Sobol's and GLISp's mean optimizer seconds per run below "
        "HB-EI's and GIPBO's (the sentence's contrast)",
        _cheap,
    ),
    Claim(
        "HB-EI, and GIPBO become costly as dimension increases",
        "Sec. 6, compute time",
        "their mean optimizer seconds per run rise with d over the synthetic problems, and "
        "are the two highest at the largest d both ran",
        _costly,
    ),
    Claim(
        "qEUBO, PrefSQP, and TuRPBO remain feasible also in high dimensions",
        "Sec. 6, compute time",
        "each ran on Styblinski-Tang 64 (d = 64) with a mean optimizer time per run at most "
        "the paper's own figure there (App. E; HB-EI and GIPBO were not run there for cost)",
        _feasible,
    ),
    # Sec. 6, policy search
    Claim(
        "TuRPBO achieves the strongest final performance in both tasks",
        "Sec. 6, policy search (warm start)",
        "Hopper and Walker2d: TuRPBO has the highest mean final best-seen",
        _turpbo_best_policy,
    ),
    Claim(
        "Our local PBO methods obtain higher cumulative performance than global baselines",
        "Sec. 6, policy search (warm start)",
        "every local method's mean final cumulative above every global method's",
        _local_cumulative_policy,
    ),
    Claim(
        "GLISp is competitive in final performance but has substantially worse cumulative "
        "performance",
        "Sec. 6, policy search (warm start)",
        "GLISp tied with the best final best-seen, its mean cumulative below every local method's",
        _glisp_policy,
    ),
    Claim(
        "without a promising initial region, purely local methods are less reliable",
        "Sec. 6, policy search; App. D.6",
        "each local method's mean final best-seen lower without warm start than with it, on "
        "both tasks",
        _local_less_reliable_cold,
    ),
    # App. D.4
    Claim(
        "GIPBOr performs worse than full GIPBO in 8 and 16 dimensions, especially for short "
        "lengthscales",
        "App. D.4, GP sample paths",
        "GP paths with d = 8 and 16, within and out of model: GIPBOr's mean final best-seen "
        "below GIPBO's on every one, and the mean gap larger at lengthscale 0.1 than at 0.5 "
        "(partly: below everywhere without that, or below on some)",
        _gipbor_below_gipbo_low_d,
    ),
    Claim(
        "In 32 dimensions, this advantage largely vanishes",
        "App. D.4, GP sample paths",
        "each 32-D GP path: GIPBOr not significantly below GIPBO (paired Wilcoxon of the "
        "two), and the mean gap GIPBO − GIPBOr smaller than at d = 8 and 16 (same setting "
        "and lengthscale)",
        _gipbor_gap_vanishes_32,
    ),
    Claim(
        "Comparing the within and out-of model comparison, especially GIPBO and GIPBOr degrade "
        "in performance, when the model is not well-specified",
        "App. D.4, GP sample paths",
        "GP paths run in both settings: each of GIPBO and GIPBOr loses more mean final "
        "best-seen from within to out of model (averaged over the paths) than every other "
        "model-based algorithm (qEUBO, HB-EI, PrefSQP, TuRPBO)",
        _gipbo_degrades_out_of_model,
    ),
    Claim(
        "In the within-model comparison, the HB-EI method performs competitively also for "
        "short lengthscales",
        "App. D.4, GP sample paths",
        "within model, lengthscale 0.1: HB-EI tied with the best final best-seen at every d",
        _hbei_competitive_within,
    ),
    # App. D.6, without warm start
    Claim(
        "Starting from a bad initialization leads to a performance degrade of the gradient "
        "based-search methods, that perform even worse than random search",
        "App. D.6, policy search without warm start",
        "each task: GIPBO's, GIPBOr's and PrefSQP's mean final best-seen lower than with warm "
        "start and below Sobol's",
        _gradient_below_random_cold,
    ),
    Claim(
        "in terms of cumulative performance, they still perform better or equally to GLISp "
        "which has a higher best observed performance",
        "App. D.6, policy search without warm start",
        "each task: GIPBO, GIPBOr and PrefSQP not significantly below GLISp in final "
        "cumulative (paired Wilcoxon of the two), and GLISp's mean final best-seen above theirs",
        _gradient_cumulative_vs_glisp_cold,
    ),
    Claim(
        "TuRBO performs consistently well in the experiments, however, the final performance "
        "is not better than random search in the hopper example",
        "App. D.6, policy search without warm start",
        "TuRPBO tied with the best final best-seen on both tasks, and on Hopper not "
        "significantly above Sobol",
        _turpbo_cold,
    ),
    # App. D.7
    Claim(
        "[PrefSQP variants:] in the synthetic setting, all variants perform similarly",
        "App. D.7, PrefSQP ablation",
        "Levy 32 and Styblinski-Tang 32: every variant (Thompson, full step, EUBO line search, EV "
        "subproblem) tied with the best final best-seen",
        _prefsqp_variants_synthetic,
    ),
    Claim(
        "On the GP functions, the fixed Newton step works best",
        "App. D.7, PrefSQP ablation",
        "GP paths d = 32, both lengthscales, out of model: the full step (eta = 1) has the "
        "highest mean final best-seen of the four variants",
        _prefsqp_full_step_gp,
    ),
    Claim(
        "On the GP samples TuRPBO [with Thompson sampling] performs best",
        "App. D.7, TuRPBO ablation",
        "GP paths d = 32, both lengthscales: Thompson sampling has the highest mean final "
        "best-seen of the three acquisitions",
        _turpbo_ts_gp,
    ),
    Claim(
        "On the standard benchmarking functions, the qEUBO variant performs equivalently well",
        "App. D.7, TuRPBO ablation",
        "Levy 32 and Styblinski-Tang 32: TuRPBO with qEUBO tied with the best final best-seen",
        _turpbo_qeubo_synthetic,
    ),
    Claim(
        "All qEUBO variants perform equally over the number of experiments",
        "App. D.7, qEUBO batch sizes",
        "every problem of the ablation: q = 1, 2 and 4 tied with the best final best-seen",
        _qeubo_batches_equal,
    ),
    Claim(
        "the final performance after the number of iterations in the 32d case is still lower "
        "than all in the local variants we propose",
        "App. D.7, qEUBO batch sizes",
        "every problem of the ablation: the best qEUBO batch size's mean final best-seen below "
        "every local method's (GIPBO, GIPBOr, PrefSQP, TuRPBO out of model; Styblinski-Tang 32: "
        "the ablations' PrefSQP and TuRPBO defaults)",
        _qeubo_below_local_32,
    ),
)


def claims_table(runs: Sequence[StoredRun], alpha: float) -> list[str]:
    """The Markdown table of :data:`CLAIMS` checked against ``runs``."""
    groups = groups_of(runs, alpha)
    lines = [
        "| the paper says | where | checked as | ours | holds? |",
        "| --- | --- | --- | --- | --- |",
    ]
    for claim in CLAIMS:
        outcome = claim.check(groups)
        lines.append(
            f"| {claim.text} | {claim.where} | {claim.reading} | {outcome.ours} | {outcome.holds} |"
        )
    return lines
