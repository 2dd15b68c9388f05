"""PrefSQP next to GIPBO and TuRPBO: what keeps it behind under the oracle's noise, read from
stored runs (PrefSQP: paper Sec. 5.2, App. C.4; GIPBO: Sec. 5.1, App. C.2; TuRPBO: App. C.5;
the noise: Sec. 6, App. D.1).

``python -m localpbo_core.experiments.prefsqp_diagnosis table FOLDERS...`` prints the table of
:func:`section`; ``python -m localpbo_core.experiments.prefsqp_diagnosis gradients FOLDERS...
--out FILE`` measures the gradient cosine (below) and writes it to ``FILE`` (JSON); the section
reads every ``prefsqp_gradients*.json`` of :data:`GRADIENTS` because refitting is too slow for
the page.

Per problem, algorithm label and noise fraction (a row), means over the seeds of per-run
figures. From :mod:`localpbo_core.experiments.diagnose` (not recomputed here):

* ``flipped``: the share of decisive duels won by the point of lower true value; with noise
  ``σ`` on each of the two values a duel of true difference ``Δ`` is flipped with probability
  ``Φ(-|Δ| / (σ√2))``.
* ``|Δ|/σ``: the median true difference of the dueled pairs in units of ``σ`` (undefined
  without noise).
* ``at a bound``: the share of proposed coordinates within 1 % of the box's edge.

From the sequence of duels (each duel: a newer point against an older one, its *reference*:
PrefSQP's iterate ``x_t``, the king of GIPBO's duel chain, TuRPBO's incumbent):

* a *move* is a change of the reference point between consecutive duels (after the initial
  design); ``better moves``: the share of moves to a point of higher true value than the
  previous reference.
* a *step* is a move to a point that was never the newer point of a duel: a point adopted on
  the model's word, evaluated but not compared first. These are PrefSQP's and GIPBO's center
  updates ``x_{t+1} = Π(x_t + η p)`` (App. D.1: "the subsequent center updates are not
  immediately evaluated"); TuRPBO has none (its incumbent changes only by winning a duel), nor
  have the duel-gated options. The step's origin is the previous center ``x_t`` (the first
  center: the winner of the initial design). ``steps``: per run; ``step length``: the median
  distance, in the unit cube, from ``x_t`` to ``x_{t+1}``; ``better steps``: the share with
  ``f(x_{t+1}) > f(x_t)``; ``steps left the box``: the share whose ``x_{t+1}`` has a
  coordinate on a face of the box (within ``1e-9`` of its side): the projection ``Π`` clipped
  it, so ``x_t + η p`` left the box (``x_t`` lies in the box, which is convex). PrefSQP's full
  Newton step ``x_t + p`` is not stored; it leaves the box at least as often (for ``η ≤ 1``).
  A step that is the budget's last evaluation is dueled at once and counts as a move only.

The gradient cosine (:func:`gradient_cosines`): at up to :data:`CHECKPOINTS` steps of a run
(evenly spread over its steps; over its moves if it has none) the pairwise GP (Sec. 4) is
refitted on the points and duels before the step, hyperparameters learned (Laplace evidence),
the first checkpoint from the default start, each later one warm-started from the previous
checkpoint's fit (the run itself warm-started from every phase's fit, so the hyperparameters
may differ from the run's); the cosine is between the posterior mean's gradient
``∇μ(x_t)`` (eq. (10)) at the step's origin (without steps: at the reference point before
the move, TuRPBO's incumbent) and the true gradient there, by central finite
differences of the problem's true value in the unit cube (one-sided on a face), step
:data:`FD_STEP`. Deterministic for given runs.

A configuration (problem, algorithm label, noise fraction, seed) that several specs store is
counted once: the first read, in the order of the folders (the page's: :data:`SPECS`).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import platform
import shlex
import sys
import time
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import numpy as np

from localpbo_core.experiments.diagnose import RunDiagnosis, diagnose_run
from localpbo_core.problems.registry import make_problem
from localpbo_core.run_documents import run_files

SPECS = ("synthetic", "ablation_noise", "ablation_prefsqp_causes")
"""The specs whose runs the section reads, in this order: the paper's synthetic runs (10 %
noise), the noise ablation (noise 0 to 0.2) and the causes ablation (noise 0 and 0.1)."""

ALGORITHMS = ("prefsqp", "prefsqp_radius", "prefsqp_gated", "prefsqp_duel_ls", "gipbo", "turpbo")
"""Algorithm labels of the rows: the paper's PrefSQP, its variants of
``ablation_prefsqp_causes``, GIPBO and TuRPBO as the paper runs them."""

FACE = 1e-9
"""A coordinate lies on a face of the box within this fraction of its side."""

CHECKPOINTS = 3
"""Steps per run at which the gradient cosine is measured."""

FD_STEP = 1e-5
"""Finite-difference step of the true gradient, in the unit cube."""

GRADIENTS = Path(__file__).resolve().parents[2] / "docs" / "diagnosis"
"""The folder of the measured gradient cosines the section shows: its files
``prefsqp_gradients*.json``, written by the ``gradients`` command."""


@dataclass(frozen=True)
class Step:
    """One step (module docstring): candidate ids of the origin ``x_t`` and of ``x_{t+1}``, and
    the number of duels answered before ``x_{t+1}`` was first a reference."""

    origin: int
    target: int
    duels_before: int


@dataclass(frozen=True)
class RunMoves:
    """The moves and steps of one stored run (module docstring)."""

    moves: int
    better_moves: float
    steps: tuple[Step, ...]
    median_step: float
    better_steps: float
    left_box: float


@dataclass(frozen=True)
class RunFigures:
    """One run's row figures: its duel diagnosis and its moves."""

    problem: str
    algorithm: str
    noise: float
    seed: int
    diagnosis: RunDiagnosis
    moves: RunMoves
    path: str
    """The run file."""


def _box(problem: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    dim = int(problem.dim)
    lo = np.asarray(problem.to_native(np.zeros(dim)), dtype=np.float64)
    hi = np.asarray(problem.to_native(np.ones(dim)), dtype=np.float64)
    return lo, hi, np.where(hi > lo, hi - lo, 1.0)


def reference_moves(doc: dict[str, Any]) -> tuple[list[tuple[int, int, int]], list[Step]]:
    """The moves (old reference, new reference, duels before) and steps of a stored run."""
    design = int(doc["settings"]["initial_design"])
    moves: list[tuple[int, int, int]] = []
    steps: list[Step] = []
    dueled: set[int] = set()
    reference: int | None = None
    center: int | None = None
    for index, a in enumerate(doc["answers"]):
        first, second = int(a["first"]), int(a["second"])
        newer, older = max(first, second), min(first, second)
        if reference is None and newer < design:
            dueled.add(newer)
            continue
        if reference is None:
            reference = center = older
        elif older != reference:
            moves.append((reference, older, index))
            if older not in dueled:
                assert center is not None
                steps.append(Step(center, older, index))
                center = older
            reference = older
        dueled.add(newer)
    return moves, steps


def run_moves(doc: dict[str, Any], problem: Any) -> tuple[RunMoves, list[tuple[int, int, int]]]:
    """The :class:`RunMoves` of a stored run of ``problem`` and its moves."""
    lo, hi, side = _box(problem)
    value = {int(c["id"]): float(c["value"]) for c in doc["candidates"]}
    native = {int(c["id"]): np.asarray(c["native"], dtype=np.float64) for c in doc["candidates"]}
    moves, steps = reference_moves(doc)
    lengths = [float(np.linalg.norm((native[s.target] - native[s.origin]) / side)) for s in steps]
    on_face = [
        bool(
            np.any(
                (np.abs(native[s.target] - lo) <= FACE * side)
                | (np.abs(hi - native[s.target]) <= FACE * side)
            )
        )
        for s in steps
    ]
    return (
        RunMoves(
            moves=len(moves),
            better_moves=float(np.mean([value[n] > value[o] for o, n, _ in moves]))
            if moves
            else math.nan,
            steps=tuple(steps),
            median_step=float(np.median(lengths)) if lengths else math.nan,
            better_steps=float(np.mean([value[s.target] > value[s.origin] for s in steps]))
            if steps
            else math.nan,
            left_box=float(np.mean(on_face)) if on_face else math.nan,
        ),
        moves,
    )


# ---------------------------------------------------------------------- loading
def section_folders(paths: Iterable[str | Path]) -> list[Path]:
    """The folders of :data:`SPECS` among ``paths`` (a path named after one of them, or its
    sub-folder of that name), in :data:`SPECS` order."""
    found: list[Path] = []
    for spec in SPECS:
        for p in map(Path, paths):
            for candidate in (p, p / spec):
                if candidate.name == spec and candidate.is_dir() and candidate not in found:
                    found.append(candidate)
    return found


def _problem_key(s: dict[str, Any]) -> tuple[str, str]:
    return s["problem"], repr(sorted((s.get("problem_options") or {}).items()))


def load_figures(
    folders: Sequence[str | Path],
    algorithms: Sequence[str] = ALGORITHMS,
    problems: Sequence[str] = (),
    noises: Sequence[float] = (),
) -> tuple[list[RunFigures], dict[str, dict[str, Any]]]:
    """The :class:`RunFigures` of every run under ``folders`` (in order; a configuration
    already read is skipped) whose algorithm label is in ``algorithms`` (and problem label in
    ``problems``, noise fraction in ``noises``, when given), on problems with a run of the
    paper's PrefSQP among them; and the documents by run file (for the gradients)."""
    from localpbo_core.sweep import read_run

    made: dict[tuple[str, str], Any] = {}
    seen: set[tuple[str, str, float, int]] = set()
    out: list[RunFigures] = []
    docs: dict[str, dict[str, Any]] = {}
    for folder in folders:
        for path in run_files([folder]):
            doc = read_run(path)
            s = doc["settings"]
            meta = doc.get("run") or {}
            label = str(meta.get("algorithm_label", s["algorithm"]))
            problem_label = str(meta.get("problem_label", s["problem"]))
            noise = float(s.get("noise_fraction", 0.1))
            key = (problem_label, label, noise, int(s["seed"]))
            if (
                label not in algorithms
                or bool(meta.get("within_model", False))
                or (problems and problem_label not in problems)
                or (noises and noise not in noises)
                or key in seen
            ):
                continue
            seen.add(key)
            pkey = _problem_key(s)
            if pkey not in made:
                made[pkey] = make_problem(s["problem"], **(s.get("problem_options") or {}))
            out.append(
                RunFigures(
                    problem_label,
                    label,
                    noise,
                    int(s["seed"]),
                    diagnose_run(doc, made[pkey]),
                    run_moves(doc, made[pkey])[0],
                    str(path),
                )
            )
            docs[str(path)] = doc
    with_prefsqp = {f.problem for f in out if f.algorithm == "prefsqp"}
    return [f for f in out if f.problem in with_prefsqp], docs


# ---------------------------------------------------------------------- gradients
def true_gradient(problem: Any, theta: np.ndarray, h: float = FD_STEP) -> np.ndarray:
    """Central finite differences of ``problem.true_value`` at ``theta`` in the unit cube
    (one-sided where ``theta ± h`` leaves it)."""
    theta = np.asarray(theta, dtype=np.float64)
    g = np.empty_like(theta)
    for i in range(theta.size):
        up, down = theta.copy(), theta.copy()
        up[i] = min(theta[i] + h, 1.0)
        down[i] = max(theta[i] - h, 0.0)
        g[i] = (problem.true_value(up) - problem.true_value(down)) / (up[i] - down[i])
    return g


def checkpoint_indices(count: int, checkpoints: int = CHECKPOINTS) -> list[int]:
    """Up to ``checkpoints`` indices into ``count`` steps, evenly spread and ending at the last:
    ``ceil(k count / checkpoints) - 1`` for ``k = 1..checkpoints``, duplicates dropped (none
    for no steps)."""
    if count <= 0:
        return []
    return sorted({math.ceil(k * count / checkpoints) - 1 for k in range(1, checkpoints + 1)})


def cosine(a: np.ndarray, b: np.ndarray) -> float:
    """``a·b / (|a| |b|)`` (nan when either is zero or not finite)."""
    na, nb = float(np.linalg.norm(a)), float(np.linalg.norm(b))
    if not (na > 0 and nb > 0 and math.isfinite(na) and math.isfinite(nb)):
        return math.nan
    return float(np.dot(a, b) / (na * nb))


def gradient_cosines(
    doc: dict[str, Any], problem: Any, checkpoints: int = CHECKPOINTS
) -> list[float]:
    """The gradient cosines of one stored run at its checkpoints (module docstring)."""
    import torch

    from localpbo_core.surrogate import PairwiseGPSurrogate

    lo, _, side = _box(problem)
    theta = {
        int(c["id"]): (np.asarray(c["native"], dtype=np.float64) - lo) / side
        for c in doc["candidates"]
    }
    moves, steps = reference_moves(doc)
    points = (
        [(s.origin, s.duels_before) for s in steps]
        if steps
        else [(o, before) for o, _, before in moves]
    )
    answers = doc["answers"]
    out: list[float] = []
    previous = None
    for k in checkpoint_indices(len(points), checkpoints):
        origin, before = points[k]
        seen = answers[:before]
        decisive = [a for a in seen if a.get("kind", "decisive") == "decisive"]
        if not decisive:
            continue
        top = max(max(int(a["first"]), int(a["second"])) for a in seen)
        X = torch.tensor(
            np.clip(np.stack([theta[i] for i in range(top + 1)]), 0.0, 1.0), dtype=torch.float64
        )
        comps = torch.tensor(
            [
                [int(a["winner"]), int(a["second"] if a["winner"] == a["first"] else a["first"])]
                for a in decisive
            ],
            dtype=torch.long,
        )
        fit = PairwiseGPSurrogate.fit(X, comps, warm_start=previous)
        previous = fit
        x = torch.tensor(np.clip(theta[origin], 0.0, 1.0), dtype=torch.float64)
        model = fit.mean_gradient(x).detach().numpy().reshape(-1)
        out.append(cosine(model, true_gradient(problem, np.clip(theta[origin], 0.0, 1.0))))
    return out


def measure_gradients(
    folders: Sequence[str | Path],
    algorithms: Sequence[str] = ALGORITHMS,
    problems: Sequence[str] = (),
    noises: Sequence[float] = (),
    checkpoints: int = CHECKPOINTS,
) -> list[dict[str, Any]]:
    """Per row (problem, algorithm, noise): runs, checkpoints, mean and sample std of the
    gradient cosines of every run under ``folders`` (:func:`load_figures`'s selection)."""
    figures, docs = load_figures(folders, algorithms, problems, noises)
    made: dict[tuple[str, str], Any] = {}
    values: dict[tuple[str, str, float], list[float]] = {}
    runs: dict[tuple[str, str, float], int] = {}
    for f in figures:
        doc = docs[f.path]
        s = doc["settings"]
        pkey = _problem_key(s)
        if pkey not in made:
            made[pkey] = make_problem(s["problem"], **(s.get("problem_options") or {}))
        found = [c for c in gradient_cosines(doc, made[pkey], checkpoints) if math.isfinite(c)]
        key = (f.problem, f.algorithm, f.noise)
        values.setdefault(key, []).extend(found)
        runs[key] = runs.get(key, 0) + 1
    rows = []
    for (problem, algorithm, noise), cs in sorted(values.items()):
        rows.append(
            {
                "problem": problem,
                "algorithm": algorithm,
                "noise": noise,
                "runs": runs[(problem, algorithm, noise)],
                "checkpoints": len(cs),
                "mean": float(np.mean(cs)) if cs else math.nan,
                "std": float(np.std(cs, ddof=1)) if len(cs) > 1 else math.nan,
            }
        )
    return rows


def read_gradients(folder: Path | None = None) -> list[dict[str, Any]]:
    """The gradient files ``prefsqp_gradients*.json`` of ``folder`` (:data:`GRADIENTS` by
    default), sorted by name; a row that an earlier file holds is dropped from later ones."""
    folder = GRADIENTS if folder is None else folder
    out: list[dict[str, Any]] = []
    seen: set[tuple[str, str, float]] = set()
    for path in sorted(folder.glob("prefsqp_gradients*.json")) if folder.is_dir() else []:
        data: dict[str, Any] = json.loads(path.read_text())
        rows = []
        for r in data.get("rows") or []:
            key = (str(r["problem"]), str(r["algorithm"]), float(r["noise"]))
            if key not in seen:
                seen.add(key)
                rows.append(r)
        out.append(data | {"rows": rows, "file": path.name})
    return out


# ---------------------------------------------------------------------- the section
def _mean(values: Iterable[float]) -> float:
    finite = [v for v in values if math.isfinite(v)]
    return float(np.mean(finite)) if finite else math.nan


def _cell(x: float, fmt: str) -> str:
    return "—" if not math.isfinite(x) else format(x, fmt)


def _algorithm_order(algorithm: str) -> tuple[int, str]:
    return (ALGORITHMS.index(algorithm) if algorithm in ALGORITHMS else len(ALGORITHMS), algorithm)


def table(figures: Sequence[RunFigures], gradients: Sequence[dict[str, Any]] = ()) -> list[str]:
    """The section's Markdown table: one row per problem, algorithm label and noise fraction,
    means over the seeds (module docstring); ``gradients``: :func:`read_gradients`."""
    cosines = {
        (r["problem"], r["algorithm"], float(r["noise"])): r
        for g in gradients
        for r in g.get("rows") or []
    }
    lines = [
        "| problem | algorithm | noise | runs | flipped | median \\|Δ\\|/σ | at a bound "
        "| better moves | steps | step length | better steps | steps left the box "
        "| gradient cosine |",
        "| --- | --- " + "| ---: " * 11 + "|",
    ]
    groups: dict[tuple[str, str, float], list[RunFigures]] = {}
    for f in figures:
        groups.setdefault((f.problem, f.algorithm, f.noise), []).append(f)
    for problem, algorithm, noise in sorted(
        groups, key=lambda k: (k[0], _algorithm_order(k[1]), k[2])
    ):
        fs = groups[(problem, algorithm, noise)]
        cos = cosines.get((problem, algorithm, noise))
        cos_cell = (
            "—"
            if cos is None or not math.isfinite(float(cos["mean"]))
            else f"{float(cos['mean']):.2f} ({cos['checkpoints']})"
        )
        cells = [
            problem,
            algorithm,
            f"{noise:g}",
            str(len(fs)),
            _cell(_mean(f.diagnosis.flipped for f in fs), ".2f"),
            _cell(_mean(f.diagnosis.median_gap_sigma for f in fs), ".2f"),
            _cell(_mean(f.diagnosis.at_bound for f in fs), ".3f"),
            _cell(_mean(f.moves.better_moves for f in fs), ".2f"),
            _cell(float(np.mean([len(f.moves.steps) for f in fs])), ".1f"),
            _cell(_mean(f.moves.median_step for f in fs), ".3f"),
            _cell(_mean(f.moves.better_steps for f in fs), ".2f"),
            _cell(_mean(f.moves.left_box for f in fs), ".2f"),
            cos_cell,
        ]
        lines.append("| " + " | ".join(cells) + " |")
    return lines


def section(
    folders: Sequence[str | Path],
    gradients: Path | None = None,
    *,
    names: Sequence[str] | None = None,
    complete_seeds: Sequence[int] | None = None,
) -> list[str]:
    """The results page's section "PrefSQP: what keeps it behind" from the runs under
    ``folders`` (empty if there is no run of the paper's PrefSQP); ``gradients``: the folder
    of the gradient files (:data:`GRADIENTS` by default); ``names``: how the prose names the
    folders (their names by default); ``complete_seeds``: only these seeds, and a row only
    with every one of them stored (``localpbo report --complete-seeds``)."""
    figures, _ = load_figures(folders)
    if complete_seeds is not None:
        wanted = set(complete_seeds)
        have: dict[tuple[str, str, float], set[int]] = {}
        for f in figures:
            have.setdefault((f.problem, f.algorithm, f.noise), set()).add(f.seed)
        figures = [
            f
            for f in figures
            if f.seed in wanted and wanted <= have[(f.problem, f.algorithm, f.noise)]
        ]
    if not figures:
        return []
    names = [Path(f).name for f in folders] if names is None else list(names)
    absent = [s for s in SPECS if s not in names]
    grad = [g for g in read_gradients(gradients) if g["rows"]]
    lines = [
        "## PrefSQP: what keeps it behind",
        "",
        "PrefSQP (Sec. 5.2, App. C.4) duels `d` points of the ball of radius 0.05 around its "
        "iterate `x_t` against `x_t`, refits, and steps along the Newton direction of the "
        "posterior mean, with no duel between `x_t` and `x_{t+1}`. Diagnostics of the stored "
        f"runs in the folders {', '.join(f'`{n}`' for n in names)} of the inputs"
        + (
            f" ({' and '.join(f'`{n}`' for n in absent)}, which hold noise-free runs, "
            "would be read too; they are not among the inputs)"
            if absent
            else ""
        )
        + ", a configuration stored by several specs counted once, means over the seeds, "
        "nothing re-run "
        "(`localpbo_core/experiments/prefsqp_diagnosis.py`, which defines every column). "
        "*flipped*: decisive duels won by the truly worse point (near one half, the duels "
        "carry almost no information about the function); *median |Δ|/σ*: the true "
        "difference of the dueled pairs in units of the oracle's noise σ; *at a bound*: "
        "proposed coordinates within 1 % of the box's edge (uniform points: 2 %); *better "
        "moves*: changes of the point the duels are against (PrefSQP's `x_t`, GIPBO's duel "
        "chain's king, TuRPBO's incumbent) to a truly better point; *steps*: per run, moves "
        "to a point taken on the model's word, never dueled first (PrefSQP's and GIPBO's "
        "`x_{t+1}`; TuRPBO has none); *step length*: median distance `|x_{t+1} − x_t|` in the "
        "unit cube; *better steps*: `f(x_{t+1}) > f(x_t)`; *steps left the box*: `x_{t+1}` "
        "on a face, i.e. the projection clipped the step (PrefSQP's full Newton step `x_t + p` "
        "is not stored and leaves the box at least as often).",
        "",
        *table(figures, grad),
        "",
    ]
    if not grad:
        return [
            *lines,
            "*gradient cosine*: not measured for these runs (`python -m "
            "localpbo_core.experiments.prefsqp_diagnosis gradients` writes it into "
            "`docs/diagnosis/`).",
            "",
        ]
    lines += [
        "*gradient cosine*: mean cosine between the refitted posterior mean's gradient "
        "`∇μ(x_t)` and the true gradient at the step's origin `x_t` (TuRPBO: at its "
        "incumbent before a move), at up to "
        f"{grad[0].get('checkpoints_per_run', CHECKPOINTS)} steps per run (in brackets: the "
        "checkpoints measured; module docstring). Too slow to refit for the page, it is read "
        "from `docs/diagnosis/`, measured by",
        "",
    ]
    for g in grad:
        lines.append(
            f"* `{g['command']}` (`{g['file']}`) on {g['machine']}, {g['date']}, "
            f"in {float(g['seconds']):.0f} s;"
        )
    lines[-1] = lines[-1][:-1] + "."
    lines.append("")
    return lines


# ---------------------------------------------------------------------- CLI
def _floats(text: str) -> list[float]:
    return [float(x) for x in text.split(",") if x]


def main(argv: Sequence[str] | None = None) -> int:
    """``table``: print the section's table; ``gradients``: measure the gradient cosines and
    write them to ``--out``."""
    ap = argparse.ArgumentParser(prog="python -m localpbo_core.experiments.prefsqp_diagnosis")
    ap.add_argument("command", choices=("table", "gradients"))
    ap.add_argument("folders", nargs="+", help="result folders, read in this order")
    ap.add_argument("--problems", default="", help="problem labels, comma-separated")
    ap.add_argument(
        "--algorithms", default=",".join(ALGORITHMS), help="algorithm labels, comma-separated"
    )
    ap.add_argument("--noise", default="", help="noise fractions, comma-separated")
    ap.add_argument("--checkpoints", type=int, default=CHECKPOINTS)
    ap.add_argument("--out", default=None, help="gradients: the JSON file to write")
    args = ap.parse_args(argv)
    problems = [p for p in args.problems.split(",") if p]
    algorithms = [a for a in args.algorithms.split(",") if a]
    noises = _floats(args.noise)
    if args.command == "table":
        figures, _ = load_figures(args.folders, algorithms, problems, noises)
        print("\n".join(table(figures, read_gradients())))
        return 0
    if args.out is None:
        ap.error("gradients needs --out")
    start = time.perf_counter()
    rows = measure_gradients(args.folders, algorithms, problems, noises, args.checkpoints)
    seconds = time.perf_counter() - start
    shown = shlex.join(
        ["python", "-m", "localpbo_core.experiments.prefsqp_diagnosis"]
        + (list(argv) if argv is not None else sys.argv[1:])
    )
    doc = {
        "command": shown,
        "machine": f"{os.cpu_count()} cores, {platform.system()} {platform.machine()}",
        "date": datetime.now(UTC).strftime("%Y-%m-%d"),
        "seconds": seconds,
        "checkpoints_per_run": args.checkpoints,
        "rows": rows,
    }
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(doc, indent=1, sort_keys=True) + "\n")
    for r in rows:
        print(
            f"{r['problem']:<18}{r['algorithm']:<16}{r['noise']:>6g}{r['runs']:>5}"
            f"{r['checkpoints']:>5}{r['mean']:>8.3f}{r['std']:>8.3f}"
        )
    print(f"{out} ({seconds:.0f} s)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
