"""``localpbo report RESULTS... --out DIR``: the paper's figures and tables from stored runs
(paper Sec. 6, App. D.1 metrics, App. E compute).

Input: sweep folders (``runs/*.json.gz``), ``localpbo bench`` folders (``runs/*.json``) or run
files. Runs are grouped by (spec, problem label, variant); within a group each algorithm
label is one row. Output in ``OUT``:

* ``report.md``: per group, final best-seen and final cumulative (App. D.1 metrics on true
  values) as mean ± sample std over seeds. For each metric the algorithm with the highest
  mean is the best (**bold**); it is compared with every other algorithm by a two-sided
  **paired Wilcoxon signed-rank test** (pairs = runs with the same seed; scipy's
  ``wilcoxon``, exact for small samples), the p-values of a group and metric are
  **Holm-corrected** (:func:`holm`), and algorithms not significantly different from the best
  (adjusted p >= ``alpha``) are underlined (``<u>…</u>``). Then the compute table: optimizer
  seconds per run (mean ± std), the share of a core the runs got (:attr:`StoredRun.core_share`),
  next to the paper's App. E figure
  (:data:`localpbo_core.experiments.paper.PAPER_SECONDS`, empty where the paper reports no
  number) and the ratio paper / ours (only for runs at the default budget with default
  options, the configuration the paper timed).
* ``curves__<spec>__<problem>[__<variant>].png``: best-seen and cumulative against the
  evaluation, mean ± std over seeds (shaded), one line per algorithm.
* ``gp_summary.png`` (if GP sample-path runs are present): final best-seen against d, one
  panel per lengthscale and per within-model / out-of-model.

Deterministic: groups, rows and keys are sorted, floats have fixed formats, PNGs are written
without the software/date metadata, so the same input gives byte-identical files.
"""

from __future__ import annotations

import json
from collections import Counter
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from localpbo_core.arguments import parse_seeds
from localpbo_core.experiments.beyond import which_algorithm_section
from localpbo_core.experiments.claims import claims_table
from localpbo_core.experiments.comparisons import compare
from localpbo_core.experiments.coverage import (
    COVERAGE_SEEDS,
    checkpoint_table,
    completion_costs,
    completion_plan,
    coverage_specs,
    coverage_table,
    group_list,
)
from localpbo_core.experiments.paper import (
    PAPER_POLICY_WARM_START,
    paper_seconds,
    problem_key,
)
from localpbo_core.experiments.spec import RunLabels
from localpbo_core.provenance import CODE_CHANGED, CODE_NONE, ProvenanceTables
from localpbo_core.provenance import code_state as _code_state
from localpbo_core.run_documents import run_files
from localpbo_core.settings import SettingError


@dataclass(frozen=True)
class StoredRun(RunLabels):
    """The parts of a stored run the report uses."""

    settings: dict[str, Any]
    best_seen: np.ndarray
    cumulative: np.ndarray
    optimizer_seconds: float
    core_share: float | None = None
    """The run's process CPU seconds over its wall seconds (one thread per run: at most about
    one, lower when other processes kept it waiting, so its seconds are high by up to
    ``1 / core_share``); None for runs stored before runs recorded it."""
    cpu_seconds: float | None = None
    """The run's process CPU seconds, evaluations included (what the run costs a core); None
    for runs stored before runs recorded it."""
    reused_from: str = ""
    """``<spec>/<run_id>`` when ``localpbo sweep --reuse`` copied the run from another sweep."""
    code: dict[str, Any] | None = None
    """The run's ``code`` block (:mod:`localpbo_core.provenance`), or for a run stored without
    one the digests of the commit that stored it (``stored_by_commit``); None if neither is
    known. ``same_behaviour`` is set when recorded re-runs show its algorithm's code since
    then left the run's trace unchanged (:func:`~localpbo_core.provenance.same_behaviour`)."""
    platform: dict[str, Any] | None = None
    """Where the run was made: its ``platform`` block
    (:func:`~localpbo_core.provenance.platform_block`); None for runs stored before runs
    carried one."""
    replaced: dict[str, Any] | None = None
    """For a re-run (``localpbo sweep --rerun-changed``), what the run it replaced was and how
    far the two agree (:func:`~localpbo_core.provenance.replaced_block`): the run's own
    ``replaced`` block, or the folder's ``replaced_runs.json`` entry
    (:mod:`localpbo_core.experiments.replaced`)."""


def platform_sentence(runs: Sequence[StoredRun]) -> str:
    """How many runs say where they were made (``platform`` block) and on which CPUs and
    torch kernel levels, with their counts."""
    places = Counter(
        f"{r.platform.get('cpu')} ({r.platform.get('cpu_capability')})"
        for r in runs
        if r.platform is not None
    )
    known = sum(places.values())
    text = (
        "Where a run was made is in its `platform` block (the CPU, torch's kernel level and "
        "threads, the numerical libraries' versions, the environment variables that choose "
        "kernels; `localpbo_core/provenance.py`): the same code and settings give other digits "
        "on another CPU (notes, **Which code made the runs, and what drifts**). "
        f"{known} of {len(runs)} stored runs carry one"
    )
    if not places:
        return text + "."
    where = ", ".join(f"{n} on {p}" for p, n in sorted(places.items(), key=lambda i: -i[1]))
    return f"{text}: {where}."


# ---------------------------------------------------------------------- loading
def read_stored_run(path: Path) -> tuple[StoredRun, dict[str, Any] | None]:
    """The run stored at ``path`` as the report uses it, without its provenance (``code`` is
    None), and the document's own ``code`` block (None when it has none). Reading the file is
    the report's main cost: the document holds every candidate and answer."""
    from localpbo_core.sweep import read_run

    doc = read_run(path)
    s = doc["settings"]
    meta = doc.get("run") or {
        "spec": "bench",
        "problem_label": s["problem"],
        "algorithm_label": s["algorithm"],
        "variant": "",
        "within_model": False,
    }
    records = doc["records"]
    run = StoredRun(
        spec=meta["spec"],
        problem_label=meta["problem_label"],
        algorithm_label=meta["algorithm_label"],
        variant=meta["variant"],
        seed=int(s["seed"]),
        within_model=bool(meta["within_model"]),
        settings=s,
        best_seen=np.array([r["best_seen"] for r in records], dtype=np.float64),
        cumulative=np.array([r["cumulative"] for r in records], dtype=np.float64),
        optimizer_seconds=float(sum(r["decision_seconds"] for r in records)),
        core_share=_core_share(doc),
        cpu_seconds=doc["cpu_seconds"] if isinstance(doc.get("cpu_seconds"), float) else None,
        reused_from=str(meta.get("reused_from", "")),
        platform=doc.get("platform") if isinstance(doc.get("platform"), dict) else None,
        replaced=doc.get("replaced") if isinstance(doc.get("replaced"), dict) else None,
    )
    code = doc.get("code")
    return run, code if isinstance(code, dict) else None


def load_runs(paths: Iterable[str | Path]) -> list[StoredRun]:
    """Read every run under ``paths`` (:func:`run_files`, each by :func:`read_stored_run`). A
    folder's ``stored_code.json`` dates the runs stored without a code version by the commit
    that stored them, its ``equivalent_code.json`` says which code changes left traces
    unchanged, its ``replaced_runs.json`` what the re-runs committed without a ``replaced``
    block replaced (:mod:`localpbo_core.experiments.stored_code`,
    :mod:`localpbo_core.experiments.drift`, :mod:`localpbo_core.experiments.replaced`)."""
    from localpbo_core.experiments.replaced import REPLACED_TABLE, load_replaced

    paths = list(paths)
    folders = [Path(p) for p in paths if Path(p).is_dir()]
    tables = ProvenanceTables(folders)
    replaced: dict[Path, dict[str, Any]] = {}
    for folder in folders:
        replaced.update(load_replaced(folder / REPLACED_TABLE))
    runs = []
    for path in run_files(paths):
        run, code = read_stored_run(path)
        own = {"settings": run.settings, "code": code}
        run = replace(run, code=tables.known_code(path, own))
        if run.replaced is None:
            run = replace(run, replaced=replaced.get(path.resolve()))
        runs.append(run)
    if not runs:
        raise SettingError("results", "no stored runs found")
    keys = [(r.spec, r.problem_label, r.algorithm_label, r.variant, r.seed) for r in runs]
    if len(set(keys)) != len(keys):
        raise SettingError("results", "the same run appears twice in the inputs")
    return sorted(
        runs, key=lambda r: (r.spec, r.problem_label, r.variant, r.algorithm_label, r.seed)
    )


def _core_share(doc: dict[str, Any]) -> float | None:
    """``cpu_seconds / run_seconds`` of a stored run (:mod:`localpbo_core.sweep`), if recorded."""
    wall, cpu = doc.get("run_seconds"), doc.get("cpu_seconds")
    if not isinstance(wall, float) or not isinstance(cpu, float) or wall <= 0:
        return None
    return cpu / wall


def complete_groups(runs: Sequence[StoredRun], seeds: Sequence[int]) -> list[StoredRun]:
    """The runs of ``seeds`` in the groups (spec, problem, variant, algorithm) that have a
    stored run for every one of ``seeds``: a sweep still under way shows no partial group."""
    wanted = set(seeds)
    have: dict[tuple[str, str, str, str], set[int]] = {}
    for r in runs:
        have.setdefault((r.spec, r.problem_label, r.variant, r.algorithm_label), set()).add(r.seed)
    return [
        r
        for r in runs
        if r.seed in wanted
        and wanted <= have[(r.spec, r.problem_label, r.variant, r.algorithm_label)]
    ]


# ---------------------------------------------------------------------- tables
def _fmt(x: float) -> str:
    return f"{x:.4g}"


def _mean_std(values: np.ndarray) -> str:
    std = float(values.std(ddof=1)) if values.size > 1 else 0.0
    return f"{_fmt(float(values.mean()))} ± {_fmt(std)}"


def _mark(text: str, algorithm: str, best: str, tied: dict[str, bool]) -> str:
    if algorithm == best:
        return f"**{text}**"
    return f"<u>{text}</u>" if tied[algorithm] else text


def group_table(runs: Sequence[StoredRun], alpha: float) -> list[str]:
    """The Markdown table of one group (module docstring)."""
    algorithms = sorted({r.algorithm_label for r in runs})
    metrics = {
        "best_seen": {
            a: {r.seed: float(r.best_seen[-1]) for r in runs if r.algorithm_label == a}
            for a in algorithms
        },
        "cumulative": {
            a: {r.seed: float(r.cumulative[-1]) for r in runs if r.algorithm_label == a}
            for a in algorithms
        },
    }
    results = {m: compare(v, alpha) for m, v in metrics.items()}
    paper = _paper_finals(runs[0])
    lines = [
        "| algorithm | runs | evaluations | code | final best-seen | p (Holm) "
        "| final cumulative | p (Holm) |"
        + (" paper best-seen | paper cumulative |" if paper else ""),
        "| --- | ---: | ---: | --- | --- | ---: | --- | ---: |"
        + (" ---: | ---: |" if paper else ""),
    ]
    for a in algorithms:
        cells = [a]
        mine = [r for r in runs if r.algorithm_label == a]
        cells.append(str(len(mine)))
        cells.append("/".join(sorted({str(r.best_seen.size) for r in mine})))
        cells.append(code_cell(mine))
        for m in ("best_seen", "cumulative"):
            best, adjusted, tied = results[m]
            values = np.array(list(metrics[m][a].values()))
            cells.append(_mark(_mean_std(values), a, best, tied))
            cells.append("best" if a == best else f"{adjusted[a]:.3g}")
        if paper:
            theirs = paper.get(a)
            cells += ["--", "--"] if theirs is None else [f"{m:g} ± {sd:g}" for m, sd in theirs]
        lines.append("| " + " | ".join(cells) + " |")
    return lines


def _paper_finals(
    run: StoredRun,
) -> dict[str, tuple[tuple[float, float], tuple[float, float]]] | None:
    """The paper's final best-seen and cumulative (mean, std) per algorithm for this group, if
    the paper reports them (policy search with warm start, at its configuration)."""
    if run.spec != "policy_warm_start" or run.variant:
        return None
    return PAPER_POLICY_WARM_START.get(run.settings["problem"])


def _paper_configuration(run: StoredRun) -> bool:
    """A run as the paper timed it: the algorithm's defaults (within-model runs: the true
    hyperparameters only), the spec's default budget, and problem options that do not change
    the optimizer's work: a GP sample path's own options, a task's noise scale
    (``value_range``)."""
    s = run.settings
    options = set(s["optimizer_options"]) - ({"hyperparameters"} if run.within_model else set())
    task = set(s["problem_options"]) - {"value_range"}
    if s["problem"] == "gp_sample":
        task -= {"dim", "lengthscale", "instance"}
    return (
        run.algorithm_label == s["algorithm"]
        and not options
        and not task
        and s["budget"] is None
        and s.get("noise_fraction", 0.1) == 0.1
    )


def compute_table(runs: Sequence[StoredRun]) -> list[str]:
    """Optimizer seconds per run against the paper's App. E figure; runs that ``localpbo
    sweep --reuse`` copied from another spec are counted in the seconds cell (their seconds
    are the source's). *core share*: the mean of :attr:`StoredRun.core_share` over the runs
    that recorded it, with their count when not all did."""
    lines = [
        "| spec | problem | algorithm | runs | optimizer s/run | core share "
        "| paper s/run (App. E) | paper / ours |",
        "| --- | --- | --- | ---: | --- | --- | ---: | ---: |",
    ]
    keys = sorted({(r.spec, r.problem_label, r.variant, r.algorithm_label) for r in runs})
    for spec, problem, variant, alg in keys:
        mine = [
            r
            for r in runs
            if (r.spec, r.problem_label, r.variant, r.algorithm_label)
            == (spec, problem, variant, alg)
        ]
        secs = np.array([r.optimizer_seconds for r in mine])
        s = mine[0].settings
        paper = (
            paper_seconds(
                problem_key(s["problem"], s["problem_options"], mine[0].within_model),
                s["algorithm"],
            )
            if _paper_configuration(mine[0])
            else None
        )
        ratio = "" if paper is None or secs.mean() <= 0 else f"{paper / secs.mean():.3g}x"
        label = problem + (f" ({variant})" if variant else "")
        sources = sorted({r.reused_from.split("/")[0] for r in mine if r.reused_from})
        copied = sum(1 for r in mine if r.reused_from)
        note = f" ({copied} runs copied from {', '.join(sources)})" if copied else ""
        shares = [r.core_share for r in mine if r.core_share is not None]
        share = f"{np.mean(shares):.2f}" if shares else ""
        if shares and len(shares) < len(mine):
            share += f" ({len(shares)} of {len(mine)} runs)"
        lines.append(
            f"| {spec} | {label} | {alg} | {len(mine)} | {_mean_std(secs)}{note} | {share} | "
            f"{'' if paper is None else f'{paper:g}'} | {ratio} |"
        )
    return lines


# ---------------------------------------------------------------------- provenance
def code_state(run: StoredRun) -> str:
    """Which code made ``run``: :data:`~localpbo_core.provenance.CODE_NONE` (no code version
    known), :data:`~localpbo_core.provenance.CODE_CURRENT` (its algorithm's sources are
    today's), :data:`~localpbo_core.provenance.CODE_SAME` (they changed, but re-runs with both
    codes on one machine gave the same trace bit for bit) or
    :data:`~localpbo_core.provenance.CODE_CHANGED`. A run stored without a code version is
    judged by the commit that stored it (:func:`localpbo_core.provenance.code_state`)."""
    return _code_state(str(run.settings["algorithm"]), run.code)


def code_cell(runs: Sequence[StoredRun]) -> str:
    """The code states of ``runs`` (one state, or counts of each)."""
    states = Counter(code_state(r) for r in runs)
    if len(states) == 1:
        return next(iter(states))
    return ", ".join(f"{n} {state}" for state, n in sorted(states.items()))


def provenance_table(runs: Sequence[StoredRun]) -> list[str]:
    """Per spec: runs with a code version of their own, runs dated by the commit that stored
    them, the commits named, and the groups (problem, variant, algorithm) whose runs were made
    by other code than today's: the algorithm's sources changed since (and no recorded re-run
    shows the same trace), or no code version known."""
    lines = [
        "| spec | runs | with a code version | dated by the storing commit | commits "
        "| algorithm changed since | no code version known |",
        "| --- | ---: | ---: | ---: | --- | --- | --- |",
    ]
    for spec in sorted({r.spec for r in runs}):
        mine = [r for r in runs if r.spec == spec]
        groups: dict[tuple[str, str, str], set[str]] = {}
        for r in mine:
            key = (r.problem_label, r.variant, r.algorithm_label)
            groups.setdefault(key, set()).add(code_state(r))
        changed = [k for k, v in groups.items() if CODE_CHANGED in v]
        unknown = [k for k, v in groups.items() if CODE_NONE in v]
        commits = Counter(
            str(r.code.get("commit"))[:10] + ("+dirty" if r.code.get("dirty") else "")
            for r in mine
            if r.code is not None
        )
        dated = sum(1 for r in mine if r.code is not None and r.code.get("stored_by_commit"))
        own = sum(1 for r in mine if r.code is not None) - dated
        lines.append(
            f"| {spec} | {len(mine)} | {own} | {dated} | "
            + (", ".join(f"{c} ({n})" for c, n in sorted(commits.items())) or "—")
            + f" | {group_list(changed, len(groups)) or '—'} "
            f"| {group_list(unknown, len(groups)) or '—'} |"
        )
    return lines


def rerun_table(runs: Sequence[StoredRun]) -> list[str]:
    """Per group (spec, problem, variant, algorithm) with re-runs (:attr:`StoredRun.replaced`):
    how many runs were re-run, the commits that had made the runs they replaced, how many
    re-runs equal the old run bit for bit and how many got the same answer in every duel, the
    largest gap where a re-run first parts from its old run, and the re-run seeds' final
    best-seen before and after (mean ± sample std). Empty without re-runs."""
    groups: dict[tuple[str, str, str, str], list[StoredRun]] = {}
    for r in runs:
        if r.replaced is not None:
            key = (r.spec, r.problem_label, r.variant, r.algorithm_label)
            groups.setdefault(key, []).append(r)
    if not groups:
        return []
    lines = [
        "| spec | problem | algorithm | re-run | replaced runs' code | same candidates "
        "| same duel answers | first gap | final best-seen before | after |",
        "| --- | --- | --- | ---: | --- | ---: | ---: | ---: | ---: | ---: |",
    ]
    for (spec, problem, variant, algorithm), members in sorted(groups.items()):
        blocks = [r.replaced for r in members if r.replaced is not None]
        commits = sorted({str(b.get("commit") or "unknown")[:10] for b in blocks})
        gaps = [b["first_gap"] for b in blocks if b["identical"] < b["candidates"]]
        gap = "—" if not gaps else ("dimension" if None in gaps else f"{max(gaps):.2g}")
        before = np.array([b["best_seen"] for b in blocks], dtype=np.float64)
        after = np.array([r.best_seen[-1] for r in members], dtype=np.float64)
        label = problem + (f" ({variant})" if variant else "")
        lines.append(
            f"| {spec} | {label} | {algorithm} | {len(blocks)} | {', '.join(commits)} "
            f"| {sum(b['identical'] == b['candidates'] for b in blocks)} "
            f"| {sum(bool(b['same_answers']) for b in blocks)} | {gap} "
            f"| {_mean_std(before)} | {_mean_std(after)} |"
        )
    return lines


def _rerun_section(runs: Sequence[StoredRun]) -> list[str]:
    table = rerun_table(runs)
    if not table:
        return []
    return [
        "### Re-runs with today's code",
        "",
        "Stored runs that `localpbo sweep --rerun-changed` made again with today's code, "
        "against the runs they replaced (the re-run's `replaced` block, or for re-runs "
        "committed before runs carried one `docs/results/replaced_runs.json` from the "
        "repository's history, `python -m localpbo_core.experiments.replaced`). *same "
        "candidates*: re-runs equal to the old run bit for bit; *same duel answers*: re-runs "
        "whose every duel had the same pair, winner and kind (the run took the same path, its "
        "candidates within floating-point gaps); *first gap*: the largest coordinate gap "
        "where a re-run first parts from its old run; finals over the re-run seeds.",
        "",
        *table,
        "",
    ]


def drift_section(paths: Iterable[str | Path]) -> list[str]:
    """The re-runs recorded in the input folders' ``equivalent_code.json`` files
    (``python -m localpbo_core.experiments.drift --why --record``) as a table: how many
    leading candidates the stored run shares with the same commit's code re-run on this
    machine (what the machine changes) and that re-run with today's code's (what the code
    changes). Empty without such a file."""
    import json

    entries = []
    for folder in (Path(p) for p in paths if Path(p).is_dir()):
        table = folder / "equivalent_code.json"
        if table.is_file():
            entries += json.loads(table.read_text())
    if not entries:
        return []
    lines = [
        "### What a re-run changes",
        "",
        "Stored runs re-made on this machine twice (`python -m localpbo_core.experiments.drift "
        "--why --record docs/results/equivalent_code.json RUN...`): with the code of the commit "
        "that made them, and with today's. Leading candidates equal bit for bit: stored against "
        "the same code here (what the machine changes) and that code against today's, both "
        "here (what the code changes); the gap is the largest coordinate difference at the "
        "first candidate where the two codes part.",
        "",
        "| algorithm | run | commit | candidates | stored = same code here "
        "| same code = today's code | gap |",
        "| --- | --- | --- | ---: | ---: | ---: | ---: |",
    ]
    for e in sorted(entries, key=lambda e: (e["algorithm"], e["run"], e["to"])):
        lines.append(
            f"| {e['algorithm']} | {Path(e['run']).name.removesuffix('.json.gz')} "
            f"| {e['commit'][:10]} | {e['candidates']} | {e.get('stored_identical', '')} "
            f"| {e['identical']} | {float(e.get('code_gap', 0.0)):.3g} |"
        )
    return [*lines, ""]


# ---------------------------------------------------------------------- noise
def noise_table(runs: Sequence[StoredRun]) -> list[str]:
    """The oracle's noise std per problem and noise level of the stored runs: the noise
    fraction × the problem's value range (paper Sec. 6: 10 % of the approximate value range;
    a task's ``value_range`` option when the spec gives one). GP sample paths have one range
    per path (per seed) and are summarised by their problem label only."""
    from localpbo_core.problems.registry import make_problem

    rows: dict[tuple[str, float], tuple[str, float | None]] = {}
    for r in runs:
        s = r.settings
        fraction = float(s.get("noise_fraction", 0.1))
        label = s["problem"] if s["problem"] != "gp_sample" else "gp_sample"
        key = (label, fraction)
        if key in rows:
            continue
        if s["problem"] == "gp_sample":
            rows[key] = ("each path's own", None)
            continue
        options = dict(s["problem_options"])
        spread = float(
            options["value_range"]
            if "value_range" in options
            else make_problem(s["problem"], **options).value_range
        )
        rows[key] = (f"{spread:.4g}", fraction * spread)
    lines = [
        "| problem | value range | noise fraction | noise std σ |",
        "| --- | ---: | ---: | ---: |",
    ]
    for (problem, fraction), (spread_cell, sigma) in sorted(rows.items()):
        cell = f"{fraction:g} × each path's range" if sigma is None else f"{sigma:.3g}"
        lines.append(f"| {problem} | {spread_cell} | {fraction:g} | {cell} |")
    return lines


# ---------------------------------------------------------------------- figures
def _pyplot() -> Any:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _save(fig: Any, path: Path) -> None:
    fig.savefig(path, dpi=100, metadata={"Software": None})
    _pyplot().close(fig)


def plot_curves(runs: Sequence[StoredRun], title: str, path: Path) -> None:
    """Best-seen and cumulative vs evaluation, mean ± std over seeds, per algorithm."""
    plt = _pyplot()
    fig, axes = plt.subplots(1, 2, figsize=(11, 4))
    for alg in sorted({r.algorithm_label for r in runs}):
        mine = [r for r in runs if r.algorithm_label == alg]
        n = min(r.best_seen.size for r in mine)
        x = np.arange(1, n + 1)
        for ax, key in zip(axes, ("best_seen", "cumulative"), strict=True):
            y = np.stack([getattr(r, key)[:n] for r in mine])
            m, s = y.mean(0), y.std(0)
            ax.plot(x, m, label=alg)
            ax.fill_between(x, m - s, m + s, alpha=0.2)
    for ax, key in zip(axes, ("best-seen f", "cumulative f"), strict=True):
        ax.set_xlabel("evaluation")
        ax.set_ylabel(key)
        ax.set_title(f"{title}: {key} (mean ± std)")
        ax.legend(fontsize=8)
    fig.tight_layout()
    _save(fig, path)


def gp_summary_runs(runs: Sequence[StoredRun]) -> list[StoredRun]:
    """The runs the GP summary draws: GP sample paths at the paper's conditions, algorithms
    as they are (an entry without its own label, e.g. not ``turpbo_ts_discrete``) and no
    variant (the noise ablation's noise levels have their own tables and curves), each
    experiment once (a run another spec stored with the same settings and model setting, e.g.
    the GLISp calibration's default GLISp, counts once)."""
    seen: set[tuple[str, bool]] = set()
    out = []
    for r in runs:
        if r.settings["problem"] != "gp_sample" or r.variant:
            continue
        if r.algorithm_label != r.settings["algorithm"]:
            continue
        key = (json.dumps(r.settings, sort_keys=True), r.within_model)
        if key not in seen:
            seen.add(key)
            out.append(r)
    return out


def plot_gp_summary(runs: Sequence[StoredRun], path: Path) -> bool:
    """Final best-seen vs d per lengthscale, within- and out-of-model (paper App. D.4), of
    :func:`gp_summary_runs`."""
    gp = gp_summary_runs(runs)
    if not gp:
        return False
    plt = _pyplot()
    scales = sorted({float(r.settings["problem_options"]["lengthscale"]) for r in gp})
    modes = sorted({r.within_model for r in gp}, reverse=True)
    fig, axes = plt.subplots(
        len(modes), len(scales), figsize=(5 * len(scales), 3.6 * len(modes)), squeeze=False
    )
    for i, within in enumerate(modes):
        for j, ls in enumerate(scales):
            ax = axes[i][j]
            sel = [
                r
                for r in gp
                if r.within_model == within
                and float(r.settings["problem_options"]["lengthscale"]) == ls
            ]
            for alg in sorted({r.algorithm_label for r in sel}):
                dims = sorted(
                    {
                        int(r.settings["problem_options"]["dim"])
                        for r in sel
                        if r.algorithm_label == alg
                    }
                )
                finals = [
                    np.array(
                        [
                            r.best_seen[-1]
                            for r in sel
                            if r.algorithm_label == alg
                            and int(r.settings["problem_options"]["dim"]) == d
                        ]
                    )
                    for d in dims
                ]
                m = np.array([f.mean() for f in finals])
                s = np.array([f.std() for f in finals])
                ax.errorbar(dims, m, yerr=s, marker="o", capsize=3, label=alg)
            ax.set_xlabel("d")
            ax.set_ylabel("final best-seen f")
            ax.set_title(f"{'within' if within else 'out-of'}-model, lengthscale {ls:g}")
            ax.legend(fontsize=8)
    fig.tight_layout()
    _save(fig, path)
    return True


# ---------------------------------------------------------------------- report
def write_report(
    paths: Iterable[str | Path],
    out: Path,
    alpha: float = 0.05,
    *,
    name: str = "report.md",
    figures: str = ".",
    notes: Path | None = None,
    title: str = "localpbo report",
    complete_seeds: Sequence[int] | None = None,
) -> Path:
    """Write the report ``out/name`` and its PNGs into ``out/figures`` (module docstring);
    return the report's path. ``notes``: a Markdown file appended verbatim.
    ``complete_seeds``: tabulate only :func:`complete_groups` of these seeds (the coverage
    table counts every stored run)."""
    if not 0.0 < alpha < 1.0:
        raise SettingError("--alpha", f"must lie in (0, 1), got {alpha!r}")
    if Path(figures).is_absolute() or ".." in Path(figures).parts:
        raise SettingError("--figures", f"must be a folder inside --out, got {figures!r}")
    if notes is not None and not notes.is_file():
        raise SettingError("--notes", f"{notes} is not a file")
    paths = list(paths)
    stored = load_runs(paths)
    runs = stored if complete_seeds is None else complete_groups(stored, complete_seeds)
    if not runs:
        raise SettingError("--complete-seeds", "no group has every one of these seeds stored")
    out.mkdir(parents=True, exist_ok=True)
    fig_dir = out / figures
    fig_dir.mkdir(parents=True, exist_ok=True)
    prefix = "" if figures == "." else Path(figures).as_posix() + "/"
    lines = [
        f"# {title}",
        "",
        f"{len(runs)} runs. Mean ± sample std over seeds. **Bold**: the best mean; "
        f"<u>underlined</u>: not significantly different from the best (two-sided paired "
        f"Wilcoxon signed-rank test by seed, Holm-corrected, alpha = {alpha:g}); p (Holm): "
        "the adjusted p-value against the best.",
        "",
    ]
    groups: dict[tuple[str, str, str], list[StoredRun]] = {}
    for r in runs:
        groups.setdefault((r.spec, r.problem_label, r.variant), []).append(r)
    for (spec, problem, variant), members in sorted(groups.items()):
        png = "__".join(p for p in ("curves", spec, problem, variant) if p) + ".png"
        heading = problem + (f" ({variant})" if variant else "")
        plot_curves(members, heading, fig_dir / png)
        lines += [
            f"## {spec}: {heading}",
            "",
            *group_table(members, alpha),
            "",
            f"![curves]({prefix}{png})",
            "",
        ]
    if plot_gp_summary(runs, fig_dir / "gp_summary.png"):
        lines += [
            "## GP sample paths: final best-seen against d",
            "",
            f"![gp]({prefix}gp_summary.png)",
            "",
        ]
    lines += which_algorithm_section(runs, alpha)
    from localpbo_core.experiments import prefsqp_diagnosis

    lines += prefsqp_diagnosis.section(
        prefsqp_diagnosis.section_folders(paths), complete_seeds=complete_seeds
    )
    specs = coverage_specs(stored)
    plan = completion_plan(stored, specs, paths)
    lines += [
        "## Coverage",
        "",
        "What is stored, against the specs of the paper's experiments and every other "
        "bundled spec with stored runs (`localpbo_core/experiments/*.yaml`), at the paper's "
        f"{len(COVERAGE_SEEDS)} seeds per group (a group: one problem, variant and algorithm; "
        "the specs list more seeds).",
        "",
        *coverage_table(stored, specs),
        "",
        "To store what is missing: each command runs only the runs not stored yet (a sweep "
        "skips stored runs; `--dry-run` lists them first), here or on a Ray cluster with "
        "`--address auto` (docs/reproducing.md). `--reuse` names the folders of other specs that "
        "stored runs with the settings of missing ones (e.g. Sobol and GLISp, which take no GP "
        "hyperparameters, of the other model setting); the sweep copies those instead of "
        "computing them, and the costs below count them as free. A command started with "
        "`--in-process` in several shells splits its runs between them (a sweep claims each "
        "run before computing it), and `--time-limit 3h` starts no run that would end after "
        "the limit unless one checkpoint interval is left (the run's progress is then kept "
        "in its checkpoint for the next sweep).",
        "",
        "```",
        *(c.command for c in plan),
        "```",
        "",
        *checkpoint_table(paths),
        *(
            [
                "What each command costs, in the order above (commands by line number):",
                "",
                *completion_costs(stored, plan),
                "",
            ]
            if plan
            else []
        ),
        "## Noise",
        "",
        "The oracle's noise std σ of the stored runs: the run's noise fraction × the problem's "
        "value range (max − min over 10,000 scrambled Sobol points, seed 0, or a task's "
        "`value_range` option).",
        "",
        *noise_table(runs),
        "",
        "## Provenance",
        "",
        "Which code made the stored runs (`code` block of a run: digests of the sources it "
        "executes and of its algorithm's, git commit; `localpbo_core/provenance.py`). Runs "
        "stored before runs carried one are dated by the commit that stored them "
        "(`docs/results/stored_code.json`, `python -m localpbo_core.experiments.stored_code`): "
        "its sources are the newest that can have made them. Per group the tables above say "
        '"current" (the algorithm\'s sources are today\'s), "same behaviour" (they changed, '
        "and re-runs with the old and today's code on one machine gave the same candidates "
        'bit for bit, `docs/results/equivalent_code.json`), "changed since" (they changed '
        'after the run was stored: a rerun may differ) or "none stored". Groups made by '
        "other code than today's:",
        "",
        *provenance_table(runs),
        "",
        platform_sentence(runs),
        "",
        *_rerun_section(stored),
        *drift_section(paths),
        "## Compute time",
        "",
        "Optimizer seconds per run (ask and tell; evaluations and oracle excluded), wall "
        "time. *core share*: the run's process CPU seconds over its wall seconds, one thread "
        "per run: near 1 the run had a core to itself, below 1 other processes kept it "
        "waiting and its seconds are high by up to 1 / share (blank: stored before runs "
        "recorded it). The paper's App. E figures are per run at the paper's budget on "
        "8-core nodes; the ratio is shown only for runs at the default budget and options.",
        "",
        *compute_table(runs),
        "",
        "## The paper's claims",
        "",
        "Each claim of Sec. 6 and App. D in the paper's words, the rule it is read as "
        '(comparative words as comparisons: "best" is the highest mean, "most" a count '
        'against every other algorithm, "consistently" every problem; '
        "`localpbo_core/experiments/claims.py`), what our runs show, and whether it holds "
        '("not run": no runs for it yet).',
        "",
        *claims_table(runs, alpha),
        "",
    ]
    if notes is not None:
        lines += [notes.read_text().rstrip("\n"), ""]
    path = out / name
    path.write_text("\n".join(lines))
    return path


RESULTS_COMMAND = (
    "localpbo",
    "report",
    "docs/results",
    "docs/pending",
    "--out",
    "docs",
    "--name",
    "RESULTS.md",
    "--figures",
    "results/figures",
    "--notes",
    "docs/results/notes.md",
    "--title",
    "Results: localpbo next to the paper",
    "--complete-seeds",
    "0-9",
)
"""The command that makes ``docs/RESULTS.md`` from the runs committed under ``docs/results``
(run in the repository's root; ``docs/reproducing.md`` documents it word for word, and
:func:`write_results_page` runs exactly these arguments)."""


def results_page_args(root: Path, out: Path | None = None) -> Any:
    """:data:`RESULTS_COMMAND` parsed by ``localpbo report``'s own parser, its paths taken
    relative to ``root``; ``--out`` replaced by ``out`` if given (to compare with the committed
    page)."""
    from localpbo_core.arguments import report_parser

    args = report_parser().parse_args(list(RESULTS_COMMAND[1:]))
    args.results = [str(root / r) for r in args.results if (root / r).exists()]
    args.out = str(root / args.out if out is None else out)
    args.notes = str(root / args.notes)
    return args


def write_results_page(root: Path, out: Path | None = None) -> Path:
    """Regenerate ``docs/RESULTS.md`` of the repository at ``root`` with
    :data:`RESULTS_COMMAND` (into ``out`` instead of ``root/docs`` if given)."""
    args = results_page_args(root, out)
    return _report_of(args)


def _report_of(args: Any) -> Path:
    return write_report(
        args.results,
        Path(args.out),
        alpha=args.alpha,
        name=args.name,
        figures=args.figures,
        notes=None if args.notes is None else Path(args.notes),
        title=args.title,
        complete_seeds=_seeds_of(args.complete_seeds),
    )


def _seeds_of(text: str | None) -> list[int] | None:
    if text is None:
        return None
    try:
        return parse_seeds(text)
    except ValueError as err:
        raise SettingError("--complete-seeds", str(err).removeprefix("--seeds: ")) from err


def main_report(args: Any) -> int:
    """The ``localpbo report`` command."""
    print(f"report: {_report_of(args)}")
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m localpbo_core.report [--out DIR]``: regenerate ``docs/RESULTS.md``."""
    import argparse
    import shlex

    parser = argparse.ArgumentParser(
        prog="python -m localpbo_core.report",
        description="Regenerate docs/RESULTS.md of this checkout from the runs committed under "
        f"docs/results, i.e. run `{shlex.join(RESULTS_COMMAND)}` in the repository's root. "
        "For a report of other runs use `localpbo report --help`.",
    )
    parser.add_argument(
        "--out",
        default=None,
        help="write the page and its figures into this folder instead of docs/ "
        "(e.g. to compare with the committed page)",
    )
    args = parser.parse_args(argv)
    root = Path(__file__).resolve().parents[1]
    page = write_results_page(root, None if args.out is None else Path(args.out))
    print(f"report: {page}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
