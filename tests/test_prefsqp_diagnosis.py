"""The PrefSQP diagnosis of stored runs, checked on hand-made runs against counts by hand, and
its section of the results page."""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

from localpbo_core.experiments.prefsqp_diagnosis import (
    Step,
    checkpoint_indices,
    cosine,
    gradient_cosines,
    load_figures,
    reference_moves,
    run_moves,
    section,
    section_folders,
    table,
    true_gradient,
)
from localpbo_core.sweep import write_run
from tests.fabricated import run_document


@dataclass(frozen=True)
class Box:
    """A 2-D problem on the native box [-5, 5]^2, value range 10, true value the first native
    coordinate."""

    name: str = "box"
    dim: int = 2
    value_range: float = 10.0

    def to_native(self, theta: np.ndarray) -> np.ndarray:
        return -5.0 + 10.0 * np.asarray(theta)

    def true_value(self, theta: np.ndarray) -> float:
        return float(self.to_native(theta)[0])


def _duel(i: int, first: int, second: int, winner: int) -> dict:
    return {"duel_id": i, "first": first, "second": second, "kind": "decisive", "winner": winner}


def _doc() -> dict:
    """Initial design 0-1 (1 wins, the first center); phase at 1: queries 2, 3 lose; step to 4;
    phase at 4 run as a duel chain: 5 beats 4 (the king becomes 5), 6 loses to 5; step from the
    center 4 to 7, on the face x_2 = -5; 8 loses to 7."""
    natives = [
        [1, 1],
        [0, 0],
        [0.5, 0],
        [0, 0.5],
        [3, 4],
        [3.2, 4],
        [3, 4.3],
        [3, -5],
        [3.1, -4.6],
    ]
    values = [0.0, 1.0, 0.5, 3.0, 2.0, 1.8, 1.0, 1.5, 1.7]
    answers = [
        _duel(0, 1, 0, 1),
        _duel(1, 2, 1, 1),
        _duel(2, 3, 1, 1),  # flipped: 3 > 1
        _duel(3, 5, 4, 5),  # flipped: 1.8 < 2
        _duel(4, 6, 5, 5),
        _duel(5, 8, 7, 7),  # flipped: 1.5 < 1.7
    ]
    return run_document("gipbo", 0, natives, values, answers)


def test_moves_and_steps_match_a_hand_count() -> None:
    moves, steps = reference_moves(_doc())
    assert moves == [(1, 4, 3), (4, 5, 4), (5, 7, 5)]
    # 5 won a duel before it became the reference: a move, not a step; the step to 7 starts
    # at the center 4, not at the king 5
    assert steps == [Step(1, 4, 3), Step(4, 7, 5)]
    m, _ = run_moves(_doc(), Box())
    assert m.moves == 3
    assert m.better_moves == pytest.approx(1 / 3)  # 1 -> 4 only
    assert m.better_steps == pytest.approx(1 / 2)  # 2 > 1; 1.5 < 2
    # |(3, 4)| / 10 = 0.5 and |(0, -9)| / 10 = 0.9
    assert m.median_step == pytest.approx(0.7)
    assert m.left_box == pytest.approx(1 / 2)  # 7 lies on the face x_2 = -5


def test_a_run_without_steps() -> None:
    doc = _doc()
    # TuRPBO-like: every new reference won its duel first
    doc["answers"] = [_duel(0, 1, 0, 1), _duel(1, 2, 1, 2), _duel(2, 3, 2, 2)]
    m, _ = run_moves(doc, Box())
    assert (m.moves, m.steps, m.better_moves) == (1, (), 0.0)  # 1 -> 2: 0.5 < 1
    assert math.isnan(m.median_step) and math.isnan(m.better_steps) and math.isnan(m.left_box)


def test_the_design_chain_is_no_move() -> None:
    doc = _doc()
    doc["settings"]["initial_design"] = 3
    doc["answers"] = [_duel(0, 1, 0, 1), _duel(1, 2, 1, 2), _duel(2, 3, 2, 3), _duel(3, 4, 2, 2)]
    moves, steps = reference_moves(doc)
    assert moves == [] and steps == []  # the reference is 2, the design's winner, throughout


def test_checkpoints_and_cosine() -> None:
    assert checkpoint_indices(7) == [2, 4, 6]
    assert checkpoint_indices(2) == [0, 1]
    assert checkpoint_indices(0) == []
    assert cosine(np.array([1.0, 0.0]), np.array([1.0, 1.0])) == pytest.approx(math.sqrt(0.5))
    assert math.isnan(cosine(np.zeros(2), np.ones(2)))


def test_true_gradient_by_finite_differences() -> None:
    # d/dtheta_1 of -5 + 10 theta_1 is 10, also one-sided on the faces
    for theta in ([0.3, 0.7], [0.0, 1.0], [1.0, 0.0]):
        assert true_gradient(Box(), np.array(theta)) == pytest.approx([10.0, 0.0])


def test_gradient_cosine_of_a_run_decided_by_the_true_value() -> None:
    rng = np.random.default_rng(0)
    box = Box()
    thetas = rng.random((24, 2))
    natives = [box.to_native(t).tolist() for t in thetas]
    values = [box.true_value(t) for t in thetas]
    # center 1, queries 2-11 dueled against it, step to 12, queries 13-23 against 12
    answers = [_duel(0, 1, 0, 1 if values[1] > values[0] else 0)]
    for q in range(2, 24):
        if q == 12:
            continue
        ref = 1 if q < 12 else 12
        answers.append(_duel(len(answers), q, ref, q if values[q] > values[ref] else ref))
    if answers[0]["winner"] == 0:  # keep the first center 1: it must win the design duel
        answers[0]["winner"] = 1
    doc = {
        "settings": {"problem": "box", "seed": 0, "initial_design": 2, "noise_fraction": 0.0},
        "candidates": [
            {"id": i, "native": n, "value": v}
            for i, (n, v) in enumerate(zip(natives, values, strict=True))
        ],
        "answers": answers,
    }
    cos = gradient_cosines(doc, box)
    assert len(cos) == 1  # one step: one checkpoint, at the center 1 before the step
    assert cos[0] > 0.5
    assert gradient_cosines(doc, box) == cos  # deterministic


# ---------------------------------------------------------------------- the section
def _stored(algorithm: str, seed: int, noise: float) -> dict:
    """A Hartmann 6 run shaped as PrefSQP's: center 1, queries 2-3, step to 4 (on a face),
    query 5."""
    natives = [[0.5] * 6, [0.4] * 6, [0.41] * 6, [0.39] * 6, [0.0] + [0.6] * 5, [0.02] + [0.6] * 5]
    values = [0.1, 0.2, 0.3, 0.1, 0.5, 0.4]
    answers = [_duel(0, 1, 0, 1), _duel(1, 2, 1, 1), _duel(2, 3, 1, 1), _duel(3, 5, 4, 4)]
    records = [
        {"best_seen": max(values[: i + 1]), "cumulative": sum(values[: i + 1])}
        | {"decision_seconds": 0.0}
        for i in range(len(values))
    ]
    return {
        "schema": "localpbo/run/v1",
        "settings": {
            "algorithm": algorithm,
            "problem": "hartmann6",
            "seed": seed,
            "budget": None,
            "initial_design": 2,
            "noise_fraction": noise,
            "optimizer_options": {},
            "problem_options": {},
        },
        "candidates": [
            {"id": i, "native": n, "value": v}
            for i, (n, v) in enumerate(zip(natives, values, strict=True))
        ],
        "answers": answers,
        "records": records,
        "run": {
            "spec": "synthetic",
            "run_id": f"hartmann6__{algorithm}__seed{seed}",
            "problem_label": "hartmann6",
            "algorithm_label": algorithm,
            "variant": "",
            "seed": seed,
            "within_model": False,
        },
        "optimizer_seconds": 0.0,
    }


def _results(tmp_path: Path) -> Path:
    root = tmp_path / "results"
    for seed in (0, 1):
        write_run(
            root / "synthetic" / "runs" / f"hartmann6__prefsqp__seed{seed}.json.gz",
            _stored("prefsqp", seed, 0.1),
        )
    for name, algorithm, noise in (
        ("same", "prefsqp", 0.1),  # the configuration of synthetic's seed 0: counted once
        ("free", "prefsqp", 0.0),
        ("sobol", "sobol", 0.1),
    ):
        doc = _stored(algorithm, 0, noise)
        doc["run"] |= {"spec": "ablation_noise", "variant": f"noise{noise:g}"}
        write_run(root / "ablation_noise" / "runs" / f"{name}.json.gz", doc)
    return root


def test_section_folders_and_selection(tmp_path: Path) -> None:
    root = _results(tmp_path)
    folders = section_folders([root])
    assert folders == [root / "synthetic", root / "ablation_noise"]
    assert section_folders([root / "synthetic"]) == [root / "synthetic"]
    figures, _ = load_figures(folders)
    keys = sorted((f.algorithm, f.noise, f.seed) for f in figures)
    assert keys == [("prefsqp", 0.0, 0), ("prefsqp", 0.1, 0), ("prefsqp", 0.1, 1)]


def test_section_renders_the_hand_counted_row(tmp_path: Path) -> None:
    root = _results(tmp_path)
    lines = section(section_folders([root]), tmp_path / "absent")
    assert lines[0] == "## PrefSQP: what keeps it behind"
    text = "\n".join(lines)
    assert "`synthetic`, `ablation_noise`" in text and "`ablation_prefsqp_causes`" in text
    assert "not measured" in text
    rows = [line for line in lines if line.startswith("| hartmann6 |")]
    # noise 0.1: duel 1 flipped (2 lost with 0.3 > 0.2), 1 of 4; every gap 0.1, σ = 0.1 x the
    # value range; 1 of 24 proposed coordinates at a bound (4's first); one step 1 -> 4,
    # better, length |(-0.4, 0.2 x 5)| = 0.6, on the face
    sigma = 0.1 * 3.0100713839207427
    assert rows[1] == (
        f"| hartmann6 | prefsqp | 0.1 | 2 | 0.25 | {0.1 / sigma:.2f} | "
        f"{1 / 24:.3f} | 1.00 | 1.0 | 0.600 | 1.00 | 1.00 | — |"
    )
    assert rows[0].startswith("| hartmann6 | prefsqp | 0 | 1 | 0.25 | — |")


def test_section_shows_the_gradient_file(tmp_path: Path) -> None:
    root = _results(tmp_path)
    (tmp_path / "grad").mkdir()
    grad = tmp_path / "grad" / "prefsqp_gradients.json"
    grad.write_text(
        json.dumps(
            {
                "command": "python -m localpbo_core.experiments.prefsqp_diagnosis gradients x",
                "machine": "2 cores, Linux x86_64",
                "date": "2026-01-01",
                "seconds": 12.0,
                "checkpoints_per_run": 3,
                "rows": [
                    {
                        "problem": "hartmann6",
                        "algorithm": "prefsqp",
                        "noise": 0.1,
                        "runs": 2,
                        "checkpoints": 5,
                        "mean": 0.1234,
                        "std": 0.3,
                    }
                ],
            }
        )
    )
    (tmp_path / "grad" / "prefsqp_gradients_more.json").write_text(
        json.dumps(
            json.loads(grad.read_text())
            | {
                "command": "second",
                "rows": [
                    {
                        "problem": "hartmann6",
                        "algorithm": "prefsqp",
                        "noise": 0.1,
                        "runs": 1,
                        "checkpoints": 1,
                        "mean": 0.9,
                        "std": 0.0,
                    }
                ],
            }
        )
    )
    lines = section(section_folders([root]), tmp_path / "grad")
    assert any(
        line.startswith("| hartmann6 | prefsqp | 0.1 |") and "| 0.12 (5) |" in line
        for line in lines
    )
    text = "\n".join(lines)
    assert "(`prefsqp_gradients.json`) on 2 cores, Linux x86_64, 2026-01-01, in 12 s." in text
    assert "second" not in text  # its only row is the first file's


def test_no_section_without_prefsqp(tmp_path: Path) -> None:
    root = tmp_path / "results"
    write_run(root / "synthetic" / "runs" / "a.json.gz", _stored("turpbo", 0, 0.1))
    assert section(section_folders([root])) == []
    assert len(table([])) == 2  # the header only


def test_the_results_page_carries_the_section(tmp_path: Path) -> None:
    from localpbo_core.report import write_report

    root = _results(tmp_path)
    page = write_report([root], tmp_path / "out").read_text()
    assert "## PrefSQP: what keeps it behind" in page
    assert page.index("## PrefSQP: what keeps it behind") < page.index("## Coverage")
