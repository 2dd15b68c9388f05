"""Experiment specs: the bundled ones parse, the loader refuses bad specs naming the field."""

from __future__ import annotations

import copy
import math
from pathlib import Path

import numpy as np
import pytest
import yaml
from scipy.stats import norm

from localpbo_core.experiments import load_spec, parse_spec
from localpbo_core.experiments.spec import SPEC_DIR, duel_hyperparameters, validate_runs
from localpbo_core.problems.gp_samples import make_gp_sample
from localpbo_core.problems.oracle import DuelOracle
from localpbo_core.settings import SettingError

BUNDLED = sorted(p.stem for p in SPEC_DIR.glob("*.yaml"))
GOOD = {
    "schema": "localpbo/experiment/v1",
    "name": "t",
    "seeds": "0-1",
    "settings": {"budget": 6},
    "problems": [{"problem": "hartmann6"}],
    "algorithms": [{"algorithm": "sobol"}, {"algorithm": "turpbo", "label": "tr"}],
}


def test_every_paper_result_has_a_spec() -> None:
    for name in (
        "gp_within",
        "gp_out_of_model",
        "synthetic",
        "policy_warm_start",
        "policy_no_warm_start",
        "ablation_prefsqp_line_search",
        "ablation_turpbo_acquisition",
        "ablation_turpbo_thompson",
        "ablation_qeubo_batch",
        "ablation_noise",
        "tiny",
    ):
        assert name in BUNDLED


@pytest.mark.parametrize("name", BUNDLED)
def test_bundled_specs_parse(name: str) -> None:
    spec = parse_spec(yaml.safe_load((SPEC_DIR / f"{name}.yaml").read_text()))
    assert spec.name == name
    ids = [r.run_id for r in spec.runs(seeds=spec.seeds[:2])]  # within model: 2 paths each
    assert len(ids) == len(set(ids))


@pytest.mark.parametrize(
    "name",
    [
        "synthetic",
        "ablation_qeubo_batch",
        "ablation_turpbo_acquisition",
        "ablation_turpbo_thompson",
        "ablation_prefsqp_line_search",
        "ablation_hbei_within",
        "tiny",
        "policy_warm_start",
    ],
)
def test_bundled_specs_validate(name: str) -> None:
    validate_runs(load_spec(name, validate=False))


def test_ablations_carry_the_ei_and_ev_variants() -> None:
    labels = {
        name: {a.label: a.options for a in load_spec(name, validate=False).algorithms}
        for name in ("ablation_turpbo_acquisition", "ablation_prefsqp_line_search")
    }
    assert labels["ablation_turpbo_acquisition"]["turpbo_ei"] == {"acquisition": "ei"}
    assert labels["ablation_prefsqp_line_search"]["prefsqp_ev"] == {"subproblem": "ev"}
    assert not any(n.startswith("pending") for n in BUNDLED)


def test_policy_warm_start_is_best_of_5d_then_one_random() -> None:
    runs = load_spec("policy_warm_start", validate=False).runs()
    hopper = next(r for r in runs if r.problem_label == "hopper")
    assert hopper.settings.initial_design == 5 * 33 + 1
    assert hopper.settings.budget is None  # initial design + 10 d = 15 d + 1
    nows = load_spec("policy_no_warm_start", validate=False).runs()
    assert next(r for r in nows if r.problem_label == "hopper").settings.budget == 15 * 33 + 1


def test_within_model_gives_true_hyperparameters_and_seed_instances() -> None:
    spec = load_spec("gp_within", validate=False)
    runs = spec.runs(problems=["gp8_l0.5"], seeds=[0, 3])
    assert {(r.problem_label, r.seed) for r in runs} == {("gp8_l0.5", 0), ("gp8_l0.5", 3)}
    for r in runs:
        assert r.settings.problem_options["instance"] == r.seed
        hp = r.settings.optimizer_options.get("hyperparameters")
        if r.algorithm_label in ("sobol", "glisp"):
            assert hp is None
        else:
            path = make_gp_sample(8, 0.5, r.seed)
            sigma = 0.1 * path.value_range
            assert hp == {"lengthscale": 0.5, "outputscale": 1.0 / sigma**2}
            assert 1.0 < hp["outputscale"] < 3.0
    out = load_spec("gp_out_of_model", validate=False).runs(seeds=[0])
    assert all("hyperparameters" not in r.settings.optimizer_options for r in out)


def test_within_model_outputscale_is_the_oracles_in_probit_units() -> None:
    """The oracle's win rate for a pair matches the surrogate likelihood Phi((u+ - u-)/sqrt 2)
    with the kernel of u given to within-model runs (and not with the path's own s = 1)."""
    path = make_gp_sample(8, 0.5, 0)
    hp = duel_hyperparameters(path, 0.1)
    sigma = 0.1 * path.value_range
    points = np.random.default_rng(0).random((400, 8))
    values = path.values(points)
    gaps = np.abs(values[:, None] - values[None, :])
    i, j = np.unravel_index(np.argmin(np.abs(gaps - 1.5 * sigma)), gaps.shape)
    first, second = (i, j) if values[i] > values[j] else (j, i)
    gap = values[first] - values[second]
    oracle = DuelOracle(path, 0.1, run_seed=0)
    n = 4000
    wins = np.mean([oracle.first_wins(k, values[first], values[second]) for k in range(n)])
    predicted = norm.cdf(gap * math.sqrt(hp["outputscale"] / 1.0) / math.sqrt(2))
    unscaled = norm.cdf(gap / math.sqrt(2))  # outputscale s = 1 taken as it is
    tolerance = 4 * math.sqrt(predicted * (1 - predicted) / n)
    assert abs(wins - predicted) < tolerance
    assert abs(wins - unscaled) > tolerance


def test_within_model_refuses_noise_free_duels(tmp_path: Path) -> None:
    doc = {
        "schema": "localpbo/experiment/v1",
        "name": "t",
        "seeds": "0",
        "settings": {"noise_fraction": 0.0},
        "within_model": True,
        "problems": [
            {"problem": "gp_sample", "label": "g", "options": {"dim": 2, "lengthscale": 0.5}}
        ],
        "algorithms": [{"algorithm": "turpbo"}],
    }
    path = tmp_path / "spec.yaml"
    path.write_text(yaml.safe_dump(doc))
    with pytest.raises(SettingError) as info:
        load_spec(path)
    assert info.value.field == "within_model" and "noise-free" in info.value.reason


def test_within_model_keeps_hyperparameters_a_spec_gives() -> None:
    runs = load_spec("ablation_hbei_within", validate=False).runs(seeds=[0])
    options = {(r.algorithm_label, r.problem_label): r.settings.optimizer_options for r in runs}
    sigma = 0.1 * make_gp_sample(8, 0.1, 0).value_range
    assert options[("hbei_true", "gp8_l0.1")] == {
        "hyperparameters": {"lengthscale": 0.1, "outputscale": 1.0 / sigma**2}
    }
    assert options[("hbei_takeno", "gp8_l0.1")] == {"hyperparameters": {"lengthscale": 0.1}}


def _refusal(change, field: str, tmp_path: Path) -> None:
    doc = copy.deepcopy(GOOD)
    change(doc)
    path = tmp_path / "spec.yaml"
    path.write_text(yaml.safe_dump(doc))
    with pytest.raises(SettingError) as info:
        load_spec(path)
    assert info.value.field == field


@pytest.mark.parametrize(
    ("change", "field"),
    [
        (lambda d: d.update(sedes="0-1"), "sedes"),
        (lambda d: d.update(schema="v0"), "schema"),
        (lambda d: d.pop("seeds"), "seeds"),
        (lambda d: d.update(seeds="0,0"), "seeds"),
        (lambda d: d.update(seeds=[0, -1]), "seeds"),
        (lambda d: d.update(seeds="a-b"), "seeds"),
        (lambda d: d.update(seeds=[True]), "seeds"),
        (lambda d: d["settings"].update(budgit=3), "settings.budgit"),
        (lambda d: d["settings"].update(budget="ten"), "settings.budget"),
        (lambda d: d["settings"].update(budget=1), "settings.budget"),
        (lambda d: d["settings"].update(noise_fraction=-1), "settings.noise_fraction"),
        (lambda d: d["problems"][0].update(problem="ackley"), "problems[0].problem"),
        (lambda d: d["problems"][0].update(options={"x": 1}), "problems[0].label"),
        (
            lambda d: d["problems"].append(
                {"problem": "gp_sample", "label": "g", "options": {"dim": 2}}
            ),
            "problems[1].options.lengthscale",
        ),
        (lambda d: d["algorithms"][0].update(algorithm="hbei2"), "algorithms[0].algorithm"),
        (lambda d: d["algorithms"][1].update(optoins={}), "algorithms[1].optoins"),
        (
            lambda d: d["algorithms"][1].update(options={"batch_size": 0}),
            "algorithms[1].options.batch_size",
        ),
        (lambda d: d["algorithms"][1].update(options={"nope": 1}), "algorithms[1].options.nope"),
        (lambda d: d["algorithms"][1].update(label="sobol"), "algorithms[1].label"),
        (lambda d: d["algorithms"][1].update(label="a__b"), "algorithms[1].label"),
        (lambda d: d.update(within_model=True), "within_model"),
        (lambda d: d.update(variants=[{"settings": {}}]), "variants[0].label"),
        (
            lambda d: d.update(variants=[{"label": "v", "settings": {"noise_fraction": "x"}}]),
            "variants[0].settings.noise_fraction",
        ),
    ],
)
def test_refusals_name_the_field(change, field: str, tmp_path: Path) -> None:
    _refusal(change, field, tmp_path)


def test_unknown_spec_name() -> None:
    with pytest.raises(SettingError) as info:
        load_spec("no_such_spec")
    assert info.value.field == "spec"
