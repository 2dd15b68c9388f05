"""The coverage statements of docs/results/notes.md, README.md and docs/reproducing.md, checked
against the stored runs and the specs (the rest of the page's coverage, noise and provenance
figures are computed by the report itself)."""

from __future__ import annotations

import gzip
import json
import re
from collections import defaultdict
from pathlib import Path

import numpy as np
import pytest

import localpbo_core.report as report
from localpbo_core.experiments import load_spec
from localpbo_core.experiments.coverage import COVERAGE_SEEDS, PAPER_SPECS, coverage_table
from localpbo_core.report import noise_table
from localpbo_core.sweep import read_run

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "docs" / "results"
PENDING = ROOT / "docs" / "pending"


pytestmark = pytest.mark.usefixtures("stored_runs_read_once")


@pytest.fixture(scope="module")
def stored() -> dict[tuple[str, str, str, str], list[dict]]:
    """Run labels (``seed`` and ``settings`` among them) of every stored run by (spec,
    problem, variant, algorithm)."""
    groups: dict[tuple[str, str, str, str], list[dict]] = defaultdict(list)
    for path in sorted([*RESULTS.glob("*/runs/*.json.gz"), *PENDING.glob("*/runs/*.json.gz")]):
        run, _ = report.read_stored_run(path)
        key = (run.spec, run.problem_label, run.variant, run.algorithm_label)
        groups[key].append({"seed": run.seed, "settings": run.settings})
    return groups


def test_the_page_tabulates_exactly_the_groups_with_the_ten_seeds(stored) -> None:
    """notes: "A group (problem, variant and algorithm) enters the tables and the claims once
    all ten seeds are stored"; README: "every experiment run so far with 10 seeds". Stored
    runs have no seed outside 0-9, and the page's command keeps exactly the complete groups."""
    from localpbo_core.report import RESULTS_COMMAND

    notes = " ".join((RESULTS / "notes.md").read_text().split())
    assert (
        "A group (problem, variant and algorithm) enters the tables and the claims once all "
        "ten seeds are stored" in notes
    )
    assert "with 10 seeds" in " ".join((ROOT / "README.md").read_text().split())
    assert RESULTS_COMMAND[-2:] == ("--complete-seeds", f"0-{max(COVERAGE_SEEDS)}")
    seeds = {k: sorted(r["seed"] for r in v) for k, v in stored.items()}
    assert {k: s for k, s in seeds.items() if not set(s) <= set(COVERAGE_SEEDS)} == {}
    page = (ROOT / "docs" / "RESULTS.md").read_text()
    for (spec, problem, variant, algorithm), s in seeds.items():
        heading = f"## {spec}: {problem}" + (f" ({variant})" if variant else "")
        section = page.split(heading + "\n", 1)[1].split("\n## ", 1)[0] if heading in page else ""
        listed = f"| {algorithm} | 10 |" in section
        assert listed == (s == list(COVERAGE_SEEDS)), (spec, problem, variant, algorithm)


def test_out_of_model_sobol_and_glisp_are_the_within_model_runs() -> None:
    """notes, docs/reproducing.md: Sobol and GLISp take no GP hyperparameters, so every one
    of their out-of-model runs has the candidates (in task units) and answers of its
    within-model run."""
    pairs = low = 0
    for path in sorted((RESULTS / "gp_out_of_model" / "runs").glob("*.json.gz")):
        twin = RESULTS / "gp_within" / "runs" / path.name
        if path.name.split("__")[1] not in ("sobol", "glisp") or not twin.is_file():
            continue  # a within-model run not stored yet (d = 64, 96: Coverage lists it)
        with gzip.open(path, "rt") as fh:
            out = json.load(fh)
        with gzip.open(twin, "rt") as fh:
            within = json.load(fh)
        native = [c["native"] for c in out["candidates"]]
        assert native == [c["native"] for c in within["candidates"]], path.name
        assert out["answers"] == within["answers"], path.name
        pairs += 1
        low += path.name.split("_l")[0] in ("gp8", "gp16", "gp32")
    assert low == 2 * 6 * len(COVERAGE_SEEDS)  # Sobol, GLISp; d = 8, 16, 32 at two scales
    assert pairs >= low  # and every pair at d = 64, 96 stored so far


def test_notes_state_which_gp_runs_are_copies() -> None:
    """notes: of the GP paths' Sobol and GLISp runs, 65 GLISp runs are copies made by
    ``--reuse`` (out of model at d <= 32, within model at d = 96) and every other one was
    computed."""
    notes = " ".join((RESULTS / "notes.md").read_text().split())
    assert (
        "65 GLISp runs were copied, those out of model at d ≤ 32 and 5 within model at d = 96; "
        "the other GLISp runs and every Sobol run were computed in both settings" in notes
    )
    copies: dict[tuple[str, str, int], int] = defaultdict(int)
    for spec in ("gp_within", "gp_out_of_model"):
        for path in sorted((RESULTS / spec / "runs").glob("gp*.json.gz")):
            problem, algorithm = path.name.split("__")[:2]
            if algorithm not in ("sobol", "glisp"):
                continue
            doc = read_run(path)
            if (doc.get("run") or {}).get("reused_from"):
                copies[(spec, algorithm, int(problem[2:].split("_")[0]))] += 1
    assert sum(copies.values()) == 65
    assert {k: v for k, v in copies.items() if k[0] == "gp_within"} == {
        ("gp_within", "glisp", 96): 5
    }
    assert {k[2] for k in copies if k[0] == "gp_out_of_model"} == {8, 16, 32}
    assert {k[1] for k in copies} == {"glisp"}


def test_notes_state_glisp_time_at_d96() -> None:
    """notes, "GLISp at high n": the CPU seconds of the d = 96, l = 0.1 GLISp runs in both
    model settings (twins: the same candidates and answers), the two seeds quoted, and the
    largest ratio between twins."""
    notes = " ".join((RESULTS / "notes.md").read_text().split())
    cpu = {
        spec: [
            read_run(RESULTS / spec / "runs" / f"gp96_l0.1__glisp__seed{s}.json.gz")["cpu_seconds"]
            for s in COVERAGE_SEEDS
        ]
        for spec in ("gp_out_of_model", "gp_within")
    }
    out, within = (np.round(cpu[k]).astype(int) for k in ("gp_out_of_model", "gp_within"))
    assert (
        f"took {out.min()}–{out.max()} CPU s out of model and {within.min()}–{within.max()} s "
        "within model" in notes
    )
    for seed in (7, 4):
        assert f"seed {seed}: {out[seed]} and {within[seed]} s" in notes
    ratio = max(
        max(a / b, b / a) for a, b in zip(cpu["gp_out_of_model"], cpu["gp_within"], strict=True)
    )
    assert f"the gap between twins, up to {ratio:.1f}x," in notes


def test_reproducing_counts_the_runs_of_each_spec() -> None:
    """docs/reproducing.md's table: the runs of each spec it lists (every spec of the paper's
    experiments among them) at the spec's seeds."""
    text = (ROOT / "docs" / "reproducing.md").read_text()
    rows = dict(re.findall(r"^\| `(\w+)` \|.*\| (\d+) \|$", text, flags=re.M))
    assert set(PAPER_SPECS) <= set(rows)
    for name in rows:
        spec = load_spec(name, validate=False)
        n = len(spec.problems) * len(spec.algorithms) * len(spec.variants) * len(spec.seeds)
        assert rows.get(name) == str(n), name


def test_coverage_table_counts_what_is_stored(stored) -> None:
    """The page's coverage table (tested here on the real runs, by a count of our own)."""
    from localpbo_core.report import load_runs

    runs = load_runs([RESULTS / "synthetic", RESULTS / "policy_warm_start"])
    table = coverage_table(runs, ["synthetic", "policy_warm_start", "policy_no_warm_start"])
    rows = {line.split(" | ")[0].strip("| "): line for line in table[2:]}
    for name in ("synthetic", "policy_warm_start"):
        spec = load_spec(name, validate=False)
        groups = len(spec.problems) * len(spec.algorithms)
        seeds = [{r["seed"] for r in v} for k, v in stored.items() if k[0] == name]
        have = sum(1 for s in seeds if s >= set(COVERAGE_SEEDS))  # complete groups
        held = sum(len(s & set(COVERAGE_SEEDS)) for s in seeds)  # runs, partial groups too
        assert f"| {have} of {groups} | {held} of {groups * 10} |" in rows[name]
    assert "| 0 of 16 | 0 of 160 | every group |" in rows["policy_no_warm_start"]
    # Walker2d without GIPBO and HB-EI is what the paper ran too (App. E has no time for them)
    warm = load_spec("policy_warm_start", validate=False)
    complete = {
        k[3]
        for k, v in stored.items()
        if k[:2] == ("policy_warm_start", "walker2d")
        and {r["seed"] for r in v} >= set(COVERAGE_SEEDS)
    }
    lacking = ", ".join(sorted({a.label for a in warm.algorithms} - complete))
    assert {"gipbo", "hbei"} <= set(lacking.split(", "))
    assert rows["policy_warm_start"].endswith(f"| walker2d: {lacking} | walker2d: gipbo, hbei |")


def test_noise_table_is_the_problems_own_scale() -> None:
    """The noise std the page reports: 10 % of the code's value range (Hartmann 6 0.301,
    Rosenbrock 16 5.3e5, Levy 32 65.5), not figures copied by hand."""
    from localpbo_core.problems.registry import make_problem
    from localpbo_core.report import load_runs

    runs = load_runs([RESULTS / "synthetic"])
    rows = {line.split(" | ")[0].strip("| "): line for line in noise_table(runs)[2:]}
    for problem, expected in (
        ("hartmann6", "0.301"),
        ("rosenbrock16", "5.3e+05"),
        ("levy32", "65.5"),
    ):
        assert rows[problem].endswith(f"| 0.1 | {expected} |")
        assert f"{0.1 * make_problem(problem).value_range:.3g}" == expected


def test_reproducing_states_the_measured_run_times() -> None:
    """docs/reproducing.md's Compute section: the mean wall seconds per run it quotes, read off
    the stored runs that record them (``run_seconds``), and Walker2d TuRPBO's optimizer time."""
    text = " ".join((ROOT / "docs" / "reproducing.md").read_text().split())
    assert (
        "Hartmann 6 under 11 s; GP paths with d = 96 under 5 s within model and 16–31 s out of "
        "model for GIPBOr and PrefSQP, under 1 s for Sobol, 230 s (ℓ = 0.1) and 445 s (ℓ = 0.5) "
        "for TuRPBO within model; d = 64 65–136 s for TuRPBO and 135–191 s for qEUBO within "
        "model; Hopper without warm start 35 s (HB-EI) to 108 s (GLISp), and 1,390–1,490 s for "
        "GIPBO's first two runs" in text
    )
    assert "TuRPBO's about 1,700 s of optimizer time on average" in text

    def docs(spec: str, pattern: str) -> list[dict]:
        out = []
        for path in sorted((RESULTS / spec / "runs").glob(f"{pattern}__seed*.json.gz")):
            with gzip.open(path, "rt") as fh:
                out.append(json.load(fh))
        return out

    def mean_wall(spec: str, pattern: str) -> list[float]:
        """Per group matching ``pattern``: the mean wall seconds of its runs that record one."""
        groups: dict[str, list[float]] = defaultdict(list)
        for doc in docs(spec, pattern):
            if "run_seconds" in doc:
                groups[doc["run"]["algorithm_label"] + doc["run"]["problem_label"]].append(
                    doc["run_seconds"]
                )
        assert groups, (spec, pattern)
        return [sum(v) / len(v) for v in groups.values()]

    assert max(mean_wall("synthetic", "hartmann6__*")) < 11
    for alg in ("gipbor", "prefsqp"):
        assert max(mean_wall("gp_within", f"gp96_*__{alg}")) < 5
        out = mean_wall("gp_out_of_model", f"gp96_*__{alg}")
        assert 16 <= round(min(out)) and round(max(out)) <= 31
    for spec in ("gp_within", "gp_out_of_model"):
        assert max(mean_wall(spec, "gp96_*__sobol")) < 1
    assert [round(t) for t in mean_wall("gp_within", "gp96_l0.1__turpbo")] == [230]
    assert [round(t) for t in mean_wall("gp_within", "gp96_l0.5__turpbo")] == [445]
    assert sorted(round(t) for t in mean_wall("gp_within", "gp64_*__qeubo")) == [135, 191]
    d64 = mean_wall("gp_within", "gp64_*__turpbo") + mean_wall("gp_out_of_model", "gp64_*__turpbo")
    assert round(min(d64)) == 65 and round(max(d64)) == 136
    assert [round(t) for t in mean_wall("policy_no_warm_start", "hopper__hbei")] == [35]
    assert [round(t) for t in mean_wall("policy_no_warm_start", "hopper__glisp")] == [108]
    gipbo = [d["run_seconds"] for d in docs("policy_no_warm_start", "hopper__gipbo")[:2]]
    assert [round(t, -1) for t in gipbo] == [1490, 1390]
    walker = [d["optimizer_seconds"] for d in docs("policy_warm_start", "walker2d__turpbo")]
    assert round(sum(walker) / len(walker), -2) == 1700


def test_notes_state_what_the_reruns_changed() -> None:
    """notes, "Re-runs with today's code": the counts and means against the re-runs' records
    as the page's re-run table reads them (each re-run's ``replaced`` block, or
    ``replaced_runs.json``), and the Hopper qEUBO finals before and after."""
    from localpbo_core.provenance import identical_candidates

    notes = " ".join((RESULTS / "notes.md").read_text().split())
    runs = report.load_runs([RESULTS])
    table = [
        (r.spec, r.problem_label, r.algorithm_label, r.replaced)
        for r in runs
        if r.replaced is not None
    ]
    by_key = {(r.spec, r.problem_label, r.algorithm_label, r.seed): r for r in runs}

    def kept(specs: tuple[str, ...], algorithm: str, problems: tuple[str, ...] = ()) -> str:
        chosen = [
            b
            for spec, problem, alg, b in table
            if spec in specs and alg == algorithm and (not problems or problem in problems)
        ]
        return f"{sum(b['same_answers'] for b in chosen)} of {len(chosen)}"

    def before_after(spec: str, problem: str, algorithm: str) -> tuple[np.ndarray, np.ndarray]:
        group = [by_key[spec, problem, algorithm, seed] for seed in range(10)]
        assert all(r.replaced is not None for r in group)
        before = np.array([r.replaced["best_seen"] for r in group if r.replaced is not None])
        return before, np.array([r.best_seen[-1] for r in group])

    within = [b for spec, problem, _, b in table if spec == "gp_within" and "64" not in problem]
    within += [b for _, _, alg, b in table if alg == "sobol"]
    assert all(b["identical"] == b["candidates"] for b in within)
    assert "Within model at d ≤ 32 (fixed hyperparameters) every re-run was the old run" in notes
    out = ("gp_out_of_model",)
    both = [kept(out, a).split(" of ") for a in ("gipbor", "prefsqp")]
    answers = f"{sum(int(k) for k, _ in both)} of {sum(int(n) for _, n in both)}"
    assert f"Out of model GIPBOr and PrefSQP kept their duel answers on {answers} runs" in notes
    k, n = kept(out, "turpbo").split(" of ")
    assert f"{k} of its {n} runs kept their duel answers" in notes
    for problem in ("gp32_l0.1", "gp16_l0.5", "gp16_l0.1"):
        old, new = before_after("gp_out_of_model", problem, "turpbo")
        assert f"{problem} {old.mean():.3f} → {new.mean():.3f}" in notes
    turpbo = [kept(("synthetic",), "turpbo", (p,)) for p in ("hartmann6", "rosenbrock16")]
    assert turpbo == ["10 of 10", "6 of 10"]
    assert kept(("synthetic",), "turpbo", ("levy32", "styblinskitang64")) == "0 of 20"
    hopper = [kept(("policy_warm_start",), a, ("hopper",)) for a in ("gipbor", "prefsqp")]
    assert hopper == ["8 of 10", "9 of 10"]
    assert "GIPBOr and PrefSQP kept their duel answers on 8 and 9 of 10 runs" in notes
    early = ("hartmann6", "rosenbrock16")

    def first_of_the_day(spec: str, problem: str, algorithm: str) -> bool:
        """The re-runs the notes date 2026-11-28 morning."""
        if spec == "ablation_prefsqp_line_search":
            return True
        if spec == "ablation_turpbo_thompson":
            return problem in early
        if spec == "beyond_local_steps":
            return (algorithm == "gipbo" and problem in early) or (
                algorithm == "prefsqp" and problem in (*early, "levy32")
            )
        return False

    chosen = [b for spec, problem, alg, b in table if first_of_the_day(spec, problem, alg)]
    count = f"{sum(b['same_answers'] for b in chosen)} of {len(chosen)}"
    assert f"Rosenbrock 16) kept their duel answers on {count} runs" in notes
    small = ("gp8_l0.1", "gp8_l0.5", "gp16_l0.1", "gp16_l0.5")
    counts = [kept(out, a, small) for a in ("gipbo", "hbei", "qeubo")]
    assert (
        f"GIPBO kept its duel answers on {counts[0]} runs, HB-EI on {counts[1]} and qEUBO on "
        f"{counts[2]}"
    ) in notes
    moves = {}
    for algorithm in ("hbei", "qeubo"):
        for problem in small:
            old, new = before_after("gp_out_of_model", problem, algorithm)
            shift = abs(new.mean() - old.mean()) / old.std(ddof=1)
            moves[shift] = f"{problem} {old.mean():.3f} → {new.mean():.3f}"
    largest = max(moves)
    assert f"at most {largest:.2f} of the old group's standard deviation" in notes
    assert f"(HB-EI {moves[largest]})" in notes
    beyond = [
        identical_candidates(
            read_run(RESULTS / "beyond_hybrid" / "runs" / f"{p}__turpbo__seed{seed}.json.gz"),
            doc := read_run(RESULTS / "synthetic" / "runs" / f"{p}__turpbo__seed{seed}.json.gz"),
        )[0]
        == len(doc["candidates"])
        for p in ("hartmann6", "rosenbrock16", "levy32")
        for seed in range(10)
    ]
    assert all(beyond) and "came out as the synthetic re-runs bit for bit" in notes
    qeubo = [
        b
        for spec, problem, alg, b in table
        if (spec, problem, alg) == ("policy_warm_start", "hopper", "qeubo")
    ]
    assert {b["identical"] for b in qeubo} == {166}
    assert "shared the first 166 candidates" in notes
    assert "ending at 1600, 131, 1070 and 797 instead of 2038, 185, 961 and 254" in notes
    group = [by_key["policy_warm_start", "hopper", "qeubo", seed] for seed in range(4)]
    assert [round(r.best_seen[-1]) for r in group] == [1600, 131, 1070, 797]
    assert [round(r.replaced["best_seen"]) for r in group if r.replaced] == [2038, 185, 961, 254]


def test_notes_state_the_second_round_of_code_reruns() -> None:
    """notes, the second round of re-runs with the storing commit's code: which commits'
    re-runs were the same bit for bit with today's code, which parted and where, and how many
    runs made from their own group came out as stored, against ``equivalent_code.json``."""
    notes = " ".join((RESULTS / "notes.md").read_text().split())
    entries = json.loads((RESULTS / "equivalent_code.json").read_text())
    by_commit = defaultdict(list)
    for e in entries:
        by_commit[(e["algorithm"], e["commit"][:7])].append(e)
    same = [
        ("gipbo", "15b3128"),
        ("hbei", "f865f62"),
        ("hbei", "8517104"),
        ("qeubo", "ffbbc6e"),
        ("qeubo", "88a41bf"),
        ("sobol", "cc30989"),
        *[("turpbo", c) for c in ("d9de676", "c9c75d5", "37775bc", "9dc47de", "c5745f7")],
    ]
    parted = [
        *[(a, "cc30989") for a in ("gipbo", "gipbor", "prefsqp", "qeubo", "turpbo")],
        ("prefsqp", "ab922a0"),
        ("hbei", "208969e"),
        ("turpbo", "120cd4b"),
    ]
    assert f"{len(same)} of the {len(same) + len(parted)} were re-made bit for bit" in notes
    for key in same:
        assert any(e["identical"] == e["candidates"] for e in by_commit[key]), key
    firsts = []
    for key in parted:
        found = [e for e in by_commit[key] if e["identical"] < e["candidates"]]
        assert found, key
        firsts += [e["identical"] for e in found]
    assert f"parted from today's code at candidate {min(firsts)}–{max(firsts)}" in notes
    # the rest re-made a Hartmann 6 run of the synthetic spec, or (GIPBO at 15b3128) a run
    # another commit stored, with --commit
    own = [
        e
        for key in same + parted
        for e in by_commit[key]
        if "/synthetic/" not in e["run"] and key != ("gipbo", "15b3128")
    ]
    hartmann = {
        key
        for key in same + parted
        if any("/synthetic/runs/hartmann6__" in e["run"] for e in by_commit[key])
    }
    assert (
        f"{len(own)} from a group that commit stored, {len(hartmann)} of Hartmann 6 with `--commit`"
    ) in notes
    assert len(own) + len(hartmann) + 1 == len(same) + len(parted)
    kept = sum(e["stored_identical"] == e["candidates"] for e in own)
    assert (
        f"of the {len(own)} runs re-made from their own group with their own commit, "
        f"{kept} came out bit for bit as stored"
    ) in notes


def test_prefsqp_noise_tables_quote_the_stored_synthetic_groups() -> None:
    """notes, PrefSQP under noise: the paper's settings at 10 % and the GIPBO / GIPBOr / TuRPBO
    reference rows are the stored synthetic groups' mean final best-seen."""
    notes = (RESULTS / "notes.md").read_text()

    def mean(problem: str, algorithm: str) -> str:
        runs = RESULTS / "synthetic" / "runs"
        finals = [
            read_run(runs / f"{problem}__{algorithm}__seed{seed}.json.gz")["records"][-1][
                "best_seen"
            ]
            for seed in range(10)
        ]
        return f"{np.mean(finals):.4g}"

    for problem, heading in (
        ("hartmann6", "| Hartmann 6 |"),
        ("rosenbrock16", "| Rosenbrock 16 |"),
    ):
        table = notes.split(heading, 1)[1].split("\n\n", 1)[0]
        reference = " / ".join(mean(problem, a) for a in ("gipbo", "gipbor", "turpbo"))
        assert f"| GIPBO / GIPBOr / TuRPBO | 0.1 | {reference} |" in table
        assert f"| PrefSQP, paper settings | 0.1 | {mean(problem, 'prefsqp')} ± " in table


def test_notes_state_glisp_time_at_d64() -> None:
    """notes, "GLISp at high n": seed 0 of GLISp on the 64-D l = 0.1 GP paths within model took
    876 s at a core share of 0.72 (the stored run)."""
    notes = " ".join((RESULTS / "notes.md").read_text().split())
    assert "seed 0 took 876 s within model (core share 0.72)" in notes
    doc = read_run(RESULTS / "gp_within" / "runs" / "gp64_l0.1__glisp__seed0.json.gz")
    assert round(doc["run_seconds"]) == 876
    assert round(doc["cpu_seconds"] / doc["run_seconds"], 2) == 0.72


def test_completion_commands_store_exactly_the_missing_groups(tmp_path: Path) -> None:
    """Fabricated runs of two specs: the commands name each spec's missing groups as exact
    products (problems × algorithms), leave out the groups the paper did not run (Walker2d
    GIPBO and HB-EI), write where the spec's runs are, and reuse the folders of other specs
    that stored runs with the same settings as missing ones (same labels alone are not
    enough)."""
    from dataclasses import replace

    from localpbo_core.experiments.coverage import completion_commands, completion_plan
    from localpbo_core.report import StoredRun
    from localpbo_core.run_documents import settings_document
    from tests.fabricated import stored_run

    def runs(spec: str, problem: str, algorithm: str, seeds: range) -> list[StoredRun]:
        return [stored_run(spec, problem, algorithm, s, 0.0, 0.0) for s in seeds]

    def planned(spec: str, problem: str, algorithm: str, seeds: range) -> list[StoredRun]:
        """Runs stored with the settings ``spec`` plans for them."""
        plans = load_spec(spec, validate=False).runs([problem], [algorithm], None, list(seeds))
        return [
            replace(r, settings=settings_document(plan.settings))
            for r, plan in zip(runs(spec, problem, algorithm, seeds), plans, strict=True)
        ]

    ten = range(10)
    warm = load_spec("policy_warm_start", validate=False)
    stored = [
        r
        for a in warm.algorithms
        if a.label != "turpbo"
        for r in runs("policy_warm_start", "hopper", a.label, ten)
    ]
    stored += planned("policy_warm_start", "hopper", "turpbo", ten)
    stored += planned("policy_warm_start", "walker2d", "turpbo", range(7))  # 7 of 10 copied
    stored += runs("policy_warm_start", "walker2d", "qeubo", range(5))  # half a group
    stored += runs("beyond_hybrid_policy", "hopper", "hybrid", ten)
    (tmp_path / "b" / "policy_warm_start" / "runs").mkdir(parents=True)
    inputs = [tmp_path / "a", tmp_path / "b"]
    a, b = (p.as_posix() for p in inputs)
    specs = ["beyond_hybrid_policy", "policy_warm_start"]
    assert completion_commands(stored, specs, inputs) == [
        f"localpbo sweep beyond_hybrid_policy --out {a}/beyond_hybrid_policy --problems hopper "
        "--algorithms hybrid_c0.5,hybrid_local,hybrid_probe,hybrid_probe0.5,"
        "hybrid_probe0.5_s0.5,turpbo --seeds 0-9 "
        f"--reuse {b}/policy_warm_start",
        f"localpbo sweep beyond_hybrid_policy --out {a}/beyond_hybrid_policy --problems walker2d "
        "--algorithms hybrid,hybrid_c0.5,hybrid_local,hybrid_probe,hybrid_probe0.5,"
        "hybrid_probe0.5_s0.5,turpbo --seeds 0-9 "
        f"--reuse {b}/policy_warm_start",
        f"localpbo sweep policy_warm_start --out {b}/policy_warm_start --problems walker2d "
        "--algorithms gipbor,glisp,prefsqp,qeubo,sobol,turpbo --seeds 0-9",
    ]
    copies = {
        (g.spec, g.problem, g.algorithm): (g.runs, g.copies)
        for c in completion_plan(stored, specs, inputs)
        for g in c.groups
        if g.copies
    }
    assert copies == {
        ("beyond_hybrid_policy", "hopper", "turpbo"): (10, 10),
        ("beyond_hybrid_policy", "walker2d", "turpbo"): (10, 7),
    }
    labels_only = [r for r in stored if r.problem_label == "hopper"]
    labels_only = [replace(r, settings={**r.settings, "seed": -1}) for r in labels_only]
    assert not any(
        "--reuse" in c for c in completion_commands(labels_only, specs, inputs)
    )  # a complete TuRPBO group of other settings is no donor

    # GP paths: Sobol and GLISp of the other model setting are the same runs; qEUBO's not.
    out = [
        r
        for alg, seeds in (("glisp", ten), ("qeubo", range(2)), ("sobol", ten))
        for r in planned("gp_out_of_model", "gp8_l0.1", alg, seeds)
    ]
    plan = completion_plan(out, ["gp_within"], [b])
    wanted = [c for c in plan if any(g.problem == "gp8_l0.1" for g in c.groups)]
    by_alg = {g.algorithm: g.copies for c in wanted for g in c.groups if g.problem == "gp8_l0.1"}
    assert by_alg["glisp"] == by_alg["sobol"] == 10 and by_alg["qeubo"] == 0
    assert all(f"--reuse {b}/gp_out_of_model" in c.command for c in wanted)
    assert completion_commands(stored[: 10 * len(warm.algorithms)], ["policy_warm_start"], [b])[
        0
    ].endswith(
        "--problems walker2d --algorithms gipbor,glisp,prefsqp,qeubo,sobol,turpbo --seeds 0-9"
    )


def test_the_pages_completion_commands_run_the_missing_runs() -> None:
    """Every command of the page's Coverage section names its spec's own labels, and one of
    them, dry-run, plans exactly the runs the stored data lacks."""
    import shlex
    import subprocess
    import sys

    page = (ROOT / "docs" / "RESULTS.md").read_text()
    block = page.split("## Coverage", 1)[1].split("```\n", 2)[1]
    commands = [shlex.split(line) for line in block.splitlines()]
    assert commands, "no commands: every group stored?"
    for words in commands:
        spec = load_spec(words[2], validate=False)
        flags = dict(zip(words[3::2], words[4::2], strict=True))
        assert words[:2] == ["localpbo", "sweep"] and flags["--seeds"] == "0-9", words
        for flag, entries in (
            ("--problems", spec.problems),
            ("--algorithms", spec.algorithms),
            ("--variants", spec.variants),
        ):
            assert set(flags.get(flag, "").split(",")) - {""} <= {e.label for e in entries}
    plain = [w for w in commands if "--reuse" not in w]  # each planned run then "will run"
    words = min(plain, key=lambda w: (any(x.startswith("gp") for x in w), len(" ".join(w))))
    done = subprocess.run(
        [sys.executable, "-m", "localpbo_core.cli", "sweep", *words[2:], "--dry-run"],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=300,
        check=True,
    )
    flags = dict(zip(words[3::2], words[4::2], strict=True))
    stored = {p.name for p in (ROOT / flags["--out"] / "runs").glob("*.json.gz")}
    plan = load_spec(words[2], validate=False)
    wanted = [
        "__".join(x for x in (p.label, a.label, v.label) if x) + f"__seed{s}.json.gz"
        for p in plan.problems
        for v in plan.variants
        for a in plan.algorithms
        for s in COVERAGE_SEEDS
        if p.label in flags["--problems"].split(",")
        and a.label in flags["--algorithms"].split(",")
        and (not v.label or v.label in flags.get("--variants", "").split(","))
    ]
    lacking = [name for name in wanted if name not in stored]
    # a sweep running now (its claims) shows some as "under way" instead
    states = re.findall(r"(\d+) (will run|under way)", done.stdout.splitlines()[-1])
    planned = sum(int(n) for n, _ in states)
    assert lacking and planned == len(lacking) and ", 0 later" in done.stdout, done.stdout[-400:]


def test_completion_costs_come_from_the_nearest_stored_runs() -> None:
    """Fabricated runs: a group's own runs beat other variants', those beat the same spec's
    runs on a problem of the same kind and dimension, those other specs' in the same model
    setting, those the other setting, and for a preset last the runs of its algorithm (same
    setting first); CPU seconds beat optimizer seconds at each step; a group with nothing stored
    to estimate from is counted apart, not as free; runs the command copies cost nothing."""
    from dataclasses import replace

    from localpbo_core.experiments.coverage import (
        Completion,
        MissingGroup,
        completion_costs,
        group_cost,
    )
    from localpbo_core.report import StoredRun
    from tests.fabricated import stored_run

    def run(
        spec: str, problem: str, alg: str, seed: int, seconds: float, variant: str = "", cpu=None
    ) -> StoredRun:
        r = stored_run(spec, problem, alg, seed, 0.0, 0.0, seconds, variant=variant)
        return replace(r, cpu_seconds=cpu)

    def group(spec: str, problem: str, variant: str, alg: str, n: int = 10) -> MissingGroup:
        gp = problem.startswith("gp")
        dim = int(problem[2:].split("_")[0]) if gp else None
        name = "gp_sample" if gp else problem
        within = spec.endswith("gp_within")
        return MissingGroup(spec, problem, variant, alg, n, within, name, dim)

    runs = [
        run("ablation_noise", "levy32", "gipbo", 0, 100.0, variant="noise0"),
        run("ablation_noise", "levy32", "gipbo", 0, 200.0, variant="noise0.1"),
        run("ablation_noise", "levy32", "gipbo", 1, 50.0, variant="noise0.1", cpu=400.0),
        run("synthetic", "levy32", "gipbo", 0, 900.0),
        run("gp_within", "gp64_l0.1", "glisp", 0, 600.0, cpu=630.0),
        run("gp_out_of_model", "gp64_l0.5", "glisp", 0, 60.0),
        run("gp_within", "gp96_l0.5", "glisp", 0, 1000.0, cpu=1200.0),
        run("beyond_hybrid", "styblinskitang64", "hybrid", 0, 300.0, cpu=330.0),
        run("beyond_hybrid", "styblinskitang64", "turpbo", 0, 30.0, cpu=33.0),
        run("beyond_hybrid_gp_within", "gp64_l0.1", "hybrid", 0, 500.0),
        run("synthetic", "levy32", "gipbor", 0, 5.0),
    ]
    preset, other = "the preset's algorithm", "the other model setting"
    expected = {
        ("ablation_noise", "levy32", "noise0", "gipbo"): (100.0, "of the group; optimizer"),
        ("ablation_noise", "levy32", "noise0.2", "gipbo"): (400.0, "of other variants; CPU"),
        ("beyond_local_steps", "levy32", "", "gipbo"): (400.0, "of ablation_noise; CPU"),
        ("gp_out_of_model", "gp64_l0.1", "", "glisp"): (60.0, "of gp64_l0.5; optimizer"),
        ("gp_out_of_model", "gp96_l0.5", "", "glisp"): (1200.0, f"of gp_within, {other}; CPU"),
        ("beyond_hybrid", "styblinskitang64", "", "hybrid_c0.5"): (
            330.0,
            f"of hybrid, {preset}; CPU",
        ),
        ("beyond_hybrid_gp_out_of_model", "gp64_l0.1", "", "hybrid_local"): (
            500.0,
            f"of hybrid, {preset}, {other}; optimizer",
        ),
        ("beyond_local_steps", "levy32", "", "gipbo_gated"): (400.0, f"of gipbo, {preset}; CPU"),
        ("beyond_local_steps", "levy32", "", "gipbor_gated"): (
            5.0,
            f"of gipbor, {preset}; optimizer",
        ),
    }
    for key, (seconds, basis) in expected.items():
        assert group_cost(runs, group(*key)) == (seconds, f"1 run {basis} seconds"), key
    assert group_cost(runs, group("gp_out_of_model", "gp96_l0.1", "", "glisp")) is None
    assert group_cost(runs, group("beyond_hybrid", "hartmann6", "", "hybrid_c0.5")) is None

    plan = [
        Completion(("c1",), (group("ablation_noise", "levy32", "noise0.2", "gipbo", 9),)),
        Completion(
            ("c2",),
            (
                group("gp_out_of_model", "gp64_l0.1", "", "glisp", 6),
                group("gp_out_of_model", "gp96_l0.1", "", "glisp"),
            ),
        ),
        Completion(("c3",), (group("gp_out_of_model", "gp96_l0.1", "", "glisp"),)),
    ]
    lines = completion_costs(runs, plan)
    assert (
        lines[2] == "| 1 | 9 | 1.0 | levy32/noise0.2/gipbo: 6.67 min "
        "(1 run of other variants; CPU seconds) |"
    )
    assert lines[3].startswith("| 2 | 16 | 0.1 + ? | gp64_l0.1/glisp: 1 min (")
    assert "gp96_l0.1/glisp: no stored run to estimate from" in lines[3]
    assert lines[4].startswith("| 3 | 10 | ? | ")
    assert lines[-1].startswith(
        "In all 35 runs, about 1.1 core-hours, besides 20 runs with nothing stored to estimate from"
    )
    assert completion_costs(runs, []) == []

    # Runs the command's --reuse copies cost nothing, even where nothing estimates the rest.
    within = group("gp_within", "gp96_l0.5", "", "glisp")
    unknown = group("gp_out_of_model", "gp96_l0.1", "", "glisp")
    lines = completion_costs(
        runs,
        [
            Completion(("c1",), (replace(within, copies=10),)),
            Completion(("c2",), (replace(within, copies=4),)),
            Completion(("c3",), (replace(unknown, copies=10),)),
        ],
    )
    assert lines[2:5] == [
        "| 1 | 10 | 0.0 | gp96_l0.5/glisp: 10 copied |",
        "| 2 | 10 | 2.0 | gp96_l0.5/glisp: 4 copied, 20 min (1 run of the group; CPU seconds) |",
        "| 3 | 10 | 0.0 | gp96_l0.1/glisp: 10 copied |",
    ]
    assert lines[-1].startswith(
        "In all 30 runs (24 of them copies, which cost nothing), about 2.0 core-hours: one run"
    )


def test_notes_state_what_the_last_levy32_gipbo_reruns_changed() -> None:
    """notes, "Re-runs with today's code": the last marked groups (GIPBO on Levy 32 in
    ``synthetic`` and ``beyond_local_steps``) against their re-runs' ``replaced`` blocks."""
    notes = " ".join((RESULTS / "notes.md").read_text().split())
    blocks = [
        read_run(RESULTS / spec / "runs" / f"levy32__gipbo__seed{seed}.json.gz")["replaced"]
        for spec in ("synthetic", "beyond_local_steps")
        for seed in range(10)
    ]
    assert all(b["same_answers"] and b["identical"] == 34 for b in blocks)
    assert max(b["first_gap"] for b in blocks) < 1.5e-9
    assert "`synthetic` and `beyond_local_steps` (20 runs)" in notes
    assert "its first 34 candidates bit for bit, parting at the 35th by at most 1.4e-9" in notes


def _seeds_named(text: str) -> list[int]:
    """``"0, 1 and 2"`` -> ``[0, 1, 2]``."""
    return [int(s) for s in re.split(r", | and ", text)]


def test_notes_state_glisp_time_on_walker2d() -> None:
    """notes, "GLISp at high n": the Walker2d warm-start GLISp runs of the seeds the sentence
    names, which are every stored seed, in CPU seconds, the decision after the warm start
    (glis's first recalibration), the mean of the later decisions, and the seeds that are
    fastest and slowest in all three."""
    notes = " ".join((RESULTS / "notes.md").read_text().split())
    found = re.search(
        r"the stored warm-start runs of seeds ([\d, and]+?) took (\d+)–(\d+) CPU s", notes
    )
    assert found, "the Walker2d GLISp sentence is missing"
    seeds = _seeds_named(found.group(1))
    stored = sorted(
        int(path.name.split("seed")[1].split(".")[0])
        for path in (RESULTS / "policy_warm_start" / "runs").glob("walker2d__glisp__seed*.json.gz")
    )
    assert sorted(seeds) == stored, f"the sentence names seeds {seeds}, stored are {stored}"
    runs = [
        read_run(RESULTS / "policy_warm_start" / "runs" / f"walker2d__glisp__seed{s}.json.gz")
        for s in seeds
    ]
    cpu = np.array([run["cpu_seconds"] for run in runs])
    assert (int(found.group(2)), int(found.group(3))) == (round(cpu.min()), round(cpu.max()))
    warm = runs[0]["settings"]["initial_design"]
    assert all(run["settings"]["initial_design"] == warm for run in runs)
    assert f"{warm} of them the warm start" in notes
    first = np.array([run["records"][warm]["decision_seconds"] for run in runs])
    later = np.array(
        [np.mean([r["decision_seconds"] for r in run["records"][warm + 1 :]]) for run in runs]
    )
    assert (
        f"took {first.min():.0f}–{first.max():.0f} s and the later decisions "
        f"{later.min():.2f}–{later.max():.2f} s on average" in notes
    )
    slowest = {seeds[int(np.argmax(x))] for x in (cpu, first, later)}
    fastest = [seeds[int(np.argmin(x))] for x in (cpu, first, later)]
    assert len(slowest) == 1, "the sentence says one seed is the slowest in all three"
    if len(set(fastest)) == 1:
        said = f"seed {fastest[0]} the fastest and seed {min(slowest)} the slowest in all three"
    else:
        assert fastest[0] == fastest[1], "write the sentence for this order of the seeds"
        said = (
            f"seed {min(slowest)} the slowest in all three, seed {fastest[0]} the fastest in "
            f"the first two and seed {fastest[2]} in the third"
        )
    assert said in notes


def _compute_rows() -> list[list[str]]:
    """The cells of the page's compute table (docs/RESULTS.md)."""
    lines = (ROOT / "docs" / "RESULTS.md").read_text().splitlines()
    head = next(
        k
        for k, line in enumerate(lines)
        if line.startswith("| spec | problem | algorithm | runs | optimizer s/run |")
    )
    rows = []
    for line in lines[head + 2 :]:
        if not line.startswith("|"):
            break
        rows.append([cell.strip() for cell in line.strip("|").split("|")])
    return rows


def _dimension(problem: str) -> int | None:
    """d of a GP or synthetic problem label (``gp64_l0.1``, ``levy32``); None for a policy."""
    found = re.match(r"gp(\d+)_", problem) or re.search(r"(\d+)$", problem)
    return int(found.group(1)) if found else None


def test_notes_state_compute_against_the_paper() -> None:
    """notes, "Compute": GLISp's ours / paper time by size, the other groups slower than the
    paper's (each named with its ratio) and Walker2d's ratios, all from the compute table."""
    notes = " ".join((RESULTS / "notes.md").read_text().split())
    rows = _compute_rows()
    ratio = {(r[0], r[1], r[2]): float(r[7].rstrip("x")) for r in rows if r[7]}
    glisp = {k: 1 / v for k, v in ratio.items() if k[2] == "glisp"}
    small = [v for k, v in glisp.items() if (_dimension(k[1]) or 99) <= 32]
    large = [v for k, v in glisp.items() if (_dimension(k[1]) or 0) >= 64]
    hopper = glisp[("policy_warm_start", "hopper", "glisp")]
    assert (
        f"GLISp takes {min(small):.2g}–{max(small):.2g}x the paper's times at d ≤ 32, "
        f"{min(large):.2g}–{max(large):.2g}x at d ≥ 64 and {hopper:.2g}x on Hopper" in notes
    )
    assert f"({min(small):.2g}–{max(small):.2g}x its figures, compute table)" in notes
    assert ("policy_warm_start", "walker2d", "glisp") not in glisp, (
        "the compute table has Walker2d's GLISp: add it to the sentence"
    )
    slower = [k for k, v in ratio.items() if k[2] != "glisp" and v < 1]
    assert f"all but {len(slower)} are faster than the paper's" in notes
    for key in slower:
        assert f"{' '.join(key)} ({ratio[key]:.3g}x" in notes, key
    seconds = {(r[0], r[1], r[2]): float(r[4].split(" ")[0]) for r in rows}
    assert (
        f"{seconds[('gp_out_of_model', 'gp64_l0.5', 'sobol')]:.2g} s per run as stored, against "
        f"{seconds[('gp_out_of_model', 'gp64_l0.1', 'sobol')]:.2g} s on the ℓ = 0.1" in notes
    )
    names = {
        "gipbor": "GIPBOr",
        "prefsqp": "PrefSQP",
        "qeubo": "qEUBO",
        "sobol": "Sobol",
        "turpbo": "TuRPBO",
    }
    walker = {k[2]: v for k, v in ratio.items() if k[:2] == ("policy_warm_start", "walker2d")}
    assert set(walker) == set(names)
    told = ", ".join(f"{names[a]} {walker[a]:.3g}x" for a in sorted(walker)[:-1])
    last = sorted(walker)[-1]
    assert f"ratios are {told} and {names[last]} {walker[last]:.3g}x." in notes


def test_notes_state_the_qeubo_times_at_d32() -> None:
    """notes, "Compute": the stored optimizer seconds of qEUBO on the 32-D l = 0.5 paths within
    model, seeds 0-5 and 6-9 (two code versions)."""
    notes = " ".join((RESULTS / "notes.md").read_text().split())
    runs = [
        read_run(RESULTS / "gp_within" / "runs" / f"gp32_l0.5__qeubo__seed{s}.json.gz")
        for s in COVERAGE_SEEDS
    ]
    secs = np.array([run["optimizer_seconds"] for run in runs])
    assert [bool(run.get("code")) for run in runs] == [True] * 6 + [False] * 4
    new, old = np.round(secs[:6]).astype(int), np.round(secs[6:]).astype(int)
    assert (
        f"seeds 0–5 took {new.min()}–{new.max()} s as stored and seeds 6–9, stored by older "
        f"code, {old.min()}–{old.max()} s" in notes
    )


def test_notes_state_the_third_round_of_code_reruns() -> None:
    """notes, the re-runs after the run loop's checkpoint change: one Hartmann 6 run per
    registered algorithm (the hybrid twice) with 7739ca1's code and today's, all the same,
    against ``equivalent_code.json``."""
    from localpbo_core.optimizers import available_optimizers

    notes = " ".join((RESULTS / "notes.md").read_text().split())
    entries = [
        e
        for e in json.loads((RESULTS / "equivalent_code.json").read_text())
        if e["commit"].startswith("7739ca1")
    ]
    assert sorted({e["algorithm"] for e in entries}) == sorted(available_optimizers())
    assert len(entries) == len(available_optimizers()) + 1
    assert all(e["run"].split("/")[-1].startswith("hartmann6__") for e in entries)
    assert {(e["identical"], e["candidates"]) for e in entries} == {(62, 62)}
    assert (
        f"seed 0 of each of the {len(available_optimizers())} algorithms" in notes
        or "seed 0 of each of the nine algorithms" in notes
    ) and len(available_optimizers()) == 9
    assert "gave the same 62 candidates of 62 in all ten" in notes
