"""Statistics of ``localpbo report``: Holm against statsmodels, the paired Wilcoxon test
against scipy and a published example (the sign-flip permutation path bit for bit), the
best/underline marking."""

from __future__ import annotations

from dataclasses import replace
from typing import TYPE_CHECKING, Any

import numpy as np
import pytest
from scipy.stats import wilcoxon
from statsmodels.stats.multitest import multipletests

from localpbo_core.experiments.comparisons import (
    EXACT_FLIPS_MAX,
    compare,
    holm,
    paired_wilcoxon,
    sign_flip_pvalue,
)

if TYPE_CHECKING:
    from pathlib import Path

    from localpbo_core.report import StoredRun


def stored_run(
    problem_label: str,
    algorithm_label: str,
    settings: dict[str, Any],
    *,
    spec: str = "s",
    seed: int = 0,
    optimizer_seconds: float = 0.0,
    code: dict[str, Any] | None = None,
    core_share: float | None = None,
) -> StoredRun:
    """A stored run of one-point traces with these labels and settings."""
    from localpbo_core.report import StoredRun

    return StoredRun(
        spec=spec,
        problem_label=problem_label,
        algorithm_label=algorithm_label,
        variant="",
        seed=seed,
        within_model=False,
        settings=settings,
        best_seen=np.zeros(1),
        cumulative=np.zeros(1),
        optimizer_seconds=optimizer_seconds,
        core_share=core_share,
        code=code,
    )


@pytest.mark.parametrize("seed", range(5))
def test_holm_matches_statsmodels(seed: int) -> None:
    rng = np.random.default_rng(seed)
    p = rng.random(7) ** 3
    expected = multipletests(p, method="holm")[1]
    np.testing.assert_allclose(holm(list(p)), expected, rtol=0, atol=1e-15)


def test_holm_textbook_example() -> None:
    # m = 4: sorted p 0.01, 0.02, 0.03, 0.5 -> 0.04, 0.06, 0.06 (monotone), 0.5
    assert holm([0.03, 0.01, 0.5, 0.02]) == pytest.approx([0.06, 0.04, 0.5, 0.06])


def test_paired_wilcoxon_matches_scipy_and_a_published_value() -> None:
    # scipy's documented example (Cushny & Peebles via Fisher, "Design of Experiments"):
    # differences in height of cross- and self-fertilised corn plants; exact p = 0.04126
    d = np.array([6, 8, 14, 16, 23, 24, 28, 29, 41, -48, 49, 56, 60, -67, 75], dtype=float)
    assert paired_wilcoxon(d, np.zeros_like(d)) == pytest.approx(0.04126, abs=5e-6)
    rng = np.random.default_rng(3)
    x, y = rng.normal(size=12), rng.normal(0.5, size=12)
    assert paired_wilcoxon(x, y) == wilcoxon(x, y).pvalue
    assert paired_wilcoxon([1.0, 2.0], [1.0, 2.0]) == 1.0


def _tied_pairs(seed: int, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Paired samples with ties among |x - y| and, for odd seeds, zero differences."""
    rng = np.random.default_rng(seed)
    x = np.round(rng.normal(size=n), 1)
    y = np.round(rng.normal(size=n), 1)
    y[0] = x[0] - 0.5
    if n > 1:
        y[1] = x[1] + 0.5  # |d| tied with the first pair
    if seed % 2 and n > 2:
        y[2] = x[2]  # a zero difference
    return x, y


@pytest.mark.parametrize(
    ("seed", "n"), [(s, n) for s, n in enumerate((1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 10, 10, 11))]
)
def test_sign_flip_path_equals_scipy_bit_for_bit(seed: int, n: int) -> None:
    # With ties or zeros and n <= 13 scipy's wilcoxon runs an exact permutation test; the
    # vectorised one must give the same float, not a close one.
    x, y = _tied_pairs(seed, n)
    assert paired_wilcoxon(x, y) == float(wilcoxon(x, y).pvalue)
    assert sign_flip_pvalue(x - y) == float(wilcoxon(x, y).pvalue)


def test_sign_flip_path_at_its_limits() -> None:
    x, y = _tied_pairs(21, EXACT_FLIPS_MAX)
    assert paired_wilcoxon(x, y) == float(wilcoxon(x, y).pvalue)
    d = np.array([1.0, -1.0, 2.0, -2.0, 0.0, 3.0])  # every |d| tied in pairs, one zero
    assert sign_flip_pvalue(d) == float(wilcoxon(d).pvalue)
    assert sign_flip_pvalue(np.array([5.0])) == 1.0  # one flip each way: p = 2 * 1/2
    x, y = _tied_pairs(22, EXACT_FLIPS_MAX + 1)  # scipy's asymptotic branch, not ours
    assert paired_wilcoxon(x, y) == float(wilcoxon(x, y).pvalue)
    with pytest.raises(ValueError, match="1 to 13"):
        sign_flip_pvalue(np.zeros(EXACT_FLIPS_MAX + 1))
    with pytest.raises(ValueError, match="equal 1-D shapes"):
        paired_wilcoxon([1.0, 2.0], [1.0])


def test_compare_marks_best_and_ties() -> None:
    seeds = range(10)
    finals = {
        "a": {s: 10.0 + 0.1 * s for s in seeds},  # best
        "b": {s: 10.0 + 0.1 * s - (0.01 if s % 2 else -0.005) for s in seeds},  # ~ a
        "c": {s: 5.0 + 0.1 * s for s in seeds},  # clearly worse in every pair
    }
    best, adjusted, tied = compare(finals, alpha=0.05)
    assert best == "a"
    assert tied == {"a": True, "b": True, "c": False}
    assert adjusted["c"] < 0.05 <= adjusted["b"]


def test_gp_summary_leaves_out_ablation_variants() -> None:
    """Only the paper's conditions, each experiment once: not an ablation's labelled entries,
    not a noise level of the noise ablation, not a copy another spec stored."""
    from localpbo_core.report import gp_summary_runs

    def run(problem: str, algorithm: str, label: str, **extra: Any) -> StoredRun:
        settings = {"problem": problem, "algorithm": algorithm, "noise_fraction": 0.1}
        return stored_run(problem, label, {**settings, **extra})

    runs = [
        run("gp_sample", "turpbo", "turpbo"),
        run("gp_sample", "turpbo", "turpbo_ts_discrete"),
        run("gp_sample", "prefsqp", "prefsqp_full"),
        run("hartmann6", "sobol", "sobol"),
        replace(run("gp_sample", "gipbo", "gipbo", noise_fraction=0.2), variant="noise0.2"),
        replace(run("gp_sample", "turpbo", "turpbo"), spec="calibration"),  # the same settings
        run("gp_sample", "turpbo", "turpbo", initial_design=5),
    ]
    assert gp_summary_runs(runs) == [runs[0], runs[-1]]


def test_compute_table_sets_the_paper_figure_beside_runs_in_its_configuration() -> None:
    from localpbo_core.experiments.paper import paper_seconds
    from localpbo_core.report import compute_table

    def run(problem: str, label: str, problem_options: dict, **settings: object) -> StoredRun:
        return stored_run(
            label,
            "sobol",
            {
                "problem": problem,
                "algorithm": "sobol",
                "optimizer_options": {},
                "problem_options": problem_options,
                "budget": None,
                "noise_fraction": 0.1,
                **settings,
            },
            optimizer_seconds=1.1,
        )

    rows = compute_table(
        [
            run("hopper", "hopper", {"value_range": 106.4}),  # noise scale only: comparable
            run("walker2d", "walker2d_short", {"episode_steps": 50}),  # another task
            run("hartmann6", "hartmann6_b40", {}, budget=40),  # another budget
            run("gp_sample", "gp8", {"dim": 8, "lengthscale": 0.1, "instance": 0}),
        ]
    )[2:]
    cells = {row.split(" | ")[1]: row.split(" | ")[6:] for row in rows}
    hopper = paper_seconds("hopper", "sobol")
    assert hopper is not None
    assert cells["hopper"] == [f"{hopper:g}", f"{hopper / 1.1:.3g}x |"]
    assert cells["walker2d_short"] == ["", " |"]
    assert cells["hartmann6_b40"] == ["", " |"]
    assert cells["gp8"][0] == f"{paper_seconds('gp8_l0.1/out', 'sobol'):g}"


def test_compute_table_shows_the_core_share_of_the_runs_that_recorded_it() -> None:
    """The share is the mean over the runs that recorded one, with their count when some did
    not; a group without any leaves the cell blank."""
    from localpbo_core.report import compute_table

    settings = {
        "problem": "hartmann6",
        "algorithm": "sobol",
        "optimizer_options": {},
        "problem_options": {},
        "budget": None,
    }
    rows = compute_table(
        [
            stored_run("all", "sobol", settings, seed=0, core_share=0.5),
            stored_run("all", "sobol", settings, seed=1, core_share=1.0),
            stored_run("some", "sobol", settings, seed=0, core_share=0.25),
            stored_run("some", "sobol", settings, seed=1),
            stored_run("none", "sobol", settings, seed=0),
        ]
    )[2:]
    share = {row.split(" | ")[1]: row.split(" | ")[5] for row in rows}
    assert share == {"all": "0.75", "some": "0.25 (1 of 2 runs)", "none": ""}


def test_a_stored_run_reads_its_core_share(tmp_path: Path) -> None:
    """A run stored by a sweep carries its wall and CPU seconds; the report reads their
    ratio, and None from a run stored without them."""
    from localpbo_core.experiments.spec import load_spec
    from localpbo_core.report import load_runs
    from localpbo_core.sweep import execute_run, read_run, run_path, write_run

    plan = load_spec("tiny").runs(None, ["sobol"], None, [0])[0]
    doc = execute_run(plan)
    write_run(run_path(tmp_path / "new", plan), doc)
    (run,) = load_runs([tmp_path / "new"])
    assert run.core_share == doc["cpu_seconds"] / doc["run_seconds"]
    old = {k: v for k, v in read_run(run_path(tmp_path / "new", plan)).items()}
    del old["cpu_seconds"], old["run_seconds"]
    write_run(run_path(tmp_path / "old", plan), old)
    (run,) = load_runs([tmp_path / "old"])
    assert run.core_share is None


def test_provenance_per_run_group_and_spec() -> None:
    """A run with today's algorithm digest is current, another digest "changed since", none
    "none stored"; the provenance table lists the groups made by other code per spec."""
    from localpbo_core.provenance import CODE_CHANGED, CODE_CURRENT, CODE_NONE, code_block
    from localpbo_core.report import (
        code_cell,
        code_state,
        provenance_table,
    )

    today = code_block("turpbo")

    def run(spec: str, problem: str, seed: int, code: dict | None) -> StoredRun:
        settings = {"problem": problem, "algorithm": "turpbo"}
        return stored_run(problem, "turpbo", settings, spec=spec, seed=seed, code=code)

    old = {**today, "algorithm_digest": "0" * 16, "commit": "abcdef123456", "dirty": True}
    runs = [
        run("a", "hartmann6", 0, dict(today)),
        run("a", "hartmann6", 1, old),
        run("a", "levy32", 0, dict(today)),
        run("b", "levy32", 0, None),
    ]
    assert [code_state(r) for r in runs] == [CODE_CURRENT, CODE_CHANGED, CODE_CURRENT, CODE_NONE]
    assert code_cell(runs[:2]) == "1 changed since, 1 current"
    assert code_cell(runs[2:3]) == "current"
    rows = provenance_table(runs)[2:]
    commit = f"{str(today['commit'])[:10]}{'+dirty' if today['dirty'] else ''}"
    assert rows[0] == (
        f"| a | 3 | 3 | 0 | abcdef1234+dirty (1), {commit} (2) | hartmann6: turpbo | — |"
        if "abcdef1234+dirty" < commit
        else f"| a | 3 | 3 | 0 | {commit} (2), abcdef1234+dirty (1) | hartmann6: turpbo | — |"
    )
    assert rows[1] == "| b | 1 | 0 | 0 | — | — | every group |"


def test_platform_sentence_counts_where_runs_were_made() -> None:
    """The Provenance section says how many runs carry a platform block and on which CPUs
    and torch kernel levels they were made, most first."""
    from dataclasses import replace

    from localpbo_core.report import platform_sentence

    base = stored_run("hartmann6", "sobol", {"problem": "hartmann6", "algorithm": "sobol"})
    here = {"cpu": "AMD EPYC", "cpu_capability": "AVX2"}
    there = {"cpu": "Intel Xeon", "cpu_capability": "AVX512"}
    runs = [replace(base, platform=here), replace(base, platform=here)]
    runs += [replace(base, platform=there), base]
    sentence = platform_sentence(runs)
    assert sentence.endswith(
        "3 of 4 stored runs carry one: 2 on AMD EPYC (AVX2), 1 on Intel Xeon (AVX512)."
    )
    assert platform_sentence([base]).endswith("0 of 1 stored runs carry one.")


def test_runs_without_code_are_dated_by_their_storing_commit(tmp_path) -> None:
    """A run stored without a code block takes the digests of the commit that stored it
    (``stored_code.json`` beside the runs); an ``equivalent_code.json`` pair that leads to
    today's digest makes a changed run "same behaviour", a pair whose re-runs differed does
    not."""
    import gzip
    import json

    from localpbo_core.provenance import (
        CODE_CHANGED,
        CODE_CURRENT,
        CODE_NONE,
        CODE_SAME,
        code_block,
    )
    from localpbo_core.report import (
        code_state,
        load_runs,
        provenance_table,
    )

    today = code_block("sobol")["algorithm_digest"]
    runs = tmp_path / "spec" / "runs"
    runs.mkdir(parents=True)

    def write(name: str, seed: int) -> None:
        doc = {
            "schema": "localpbo/run/v1",
            "settings": {"algorithm": "sobol", "problem": "hartmann6", "seed": seed},
            "candidates": [],
            "answers": [],
            "records": [{"best_seen": 1.0, "cumulative": 1.0, "decision_seconds": 0.0}],
            "run": {
                "spec": "spec",
                "problem_label": "hartmann6",
                "algorithm_label": "sobol",
                "variant": "",
                "within_model": False,
            },
        }
        with gzip.open(runs / name, "wt") as fh:
            json.dump(doc, fh)

    for seed, name in enumerate(["now.json.gz", "old.json.gz", "older.json.gz", "bare.json.gz"]):
        write(name, seed)
    digests = {"now": today, "old": "1" * 16, "older": "2" * 16}
    (tmp_path / "stored_code.json").write_text(
        json.dumps(
            {
                "schema": "localpbo/stored-code/v1",
                "commits": {
                    c: {"digest": "d", "algorithms": {"sobol": d}} for c, d in digests.items()
                },
                "runs": {f"spec/runs/{c}.json.gz": c for c in digests},
            }
        )
    )
    entry = {"algorithm": "sobol", "candidates": 5, "run": "x", "commit": "c"}
    (tmp_path / "equivalent_code.json").write_text(
        json.dumps(
            [
                {**entry, "from": "1" * 16, "to": today, "identical": 5},
                {**entry, "from": "2" * 16, "to": today, "identical": 4},
            ]
        )
    )
    loaded = {r.seed: r for r in load_runs([tmp_path])}
    assert [code_state(loaded[s]) for s in range(4)] == [
        CODE_CURRENT,
        CODE_SAME,
        CODE_CHANGED,
        CODE_NONE,
    ]
    assert loaded[1].code is not None and loaded[1].code["commit"] == "old"
    assert provenance_table(list(loaded.values()))[2] == (
        "| spec | 4 | 0 | 3 | now (1), old (1), older (1) | every group | every group |"
    )


def test_complete_groups_keep_only_groups_with_every_seed() -> None:
    """``--complete-seeds``: a group enters the tables only with every seed stored; seeds
    outside the set are left out; a bad seed list is refused naming the flag."""
    from localpbo_core.report import _seeds_of, complete_groups
    from localpbo_core.settings import SettingError

    def run(problem: str, algorithm: str, seed: int) -> StoredRun:
        settings = {"problem": problem, "algorithm": algorithm}
        return stored_run(problem, algorithm, settings, seed=seed)

    runs = [run("p", "a", s) for s in range(4)] + [run("p", "b", s) for s in (0, 2)]
    runs += [run("q", "a", s) for s in (0, 1, 2)]
    kept = complete_groups(runs, [0, 1, 2])
    assert [(r.problem_label, r.algorithm_label, r.seed) for r in kept] == [
        ("p", "a", 0),
        ("p", "a", 1),
        ("p", "a", 2),
        ("q", "a", 0),
        ("q", "a", 1),
        ("q", "a", 2),
    ]
    assert complete_groups(runs, [5]) == []
    assert _seeds_of("0-2") == [0, 1, 2] and _seeds_of(None) is None
    with pytest.raises(SettingError) as err:
        _seeds_of("3-x")
    assert err.value.field == "--complete-seeds"
