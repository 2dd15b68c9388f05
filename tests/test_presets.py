"""Presets (:mod:`localpbo_core.presets`): a label runs its algorithm with its options exactly
as if they were given explicitly, in every path that names an algorithm."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from localpbo_core.arguments import parse_options
from localpbo_core.cli import main
from localpbo_core.experiments import load_spec, parse_spec
from localpbo_core.experiments.beyond import BEYOND_PREFIX, runnable
from localpbo_core.experiments.spec import SPEC_DIR
from localpbo_core.optimizers import available_optimizers
from localpbo_core.presets import PRESETS, available_presets, expand
from localpbo_core.settings import DEFAULT_ALGORITHM, RunSettings, SettingError

ALL = {"sampling_radius": "lengthscale", "step_normalization": "kernel", "accept_step": "duel"}


def test_every_preset_names_a_registered_algorithm_and_its_options() -> None:
    from localpbo_core.optimizers import optimizer_options

    assert not set(PRESETS) & set(available_optimizers())
    for label, preset in PRESETS.items():
        assert preset.algorithm in available_optimizers(), label
        assert set(preset.options) <= set(optimizer_options(preset.algorithm)), label
    assert DEFAULT_ALGORITHM in available_optimizers() + available_presets()


def test_settings_expand_a_preset() -> None:
    explicit = RunSettings("prefsqp", "hartmann6", seed=3, optimizer_options=ALL)
    assert RunSettings("PrefSQP_all", "hartmann6", seed=3) == explicit
    assert RunSettings("prefsqp_all", "hartmann6", seed=3, optimizer_options=ALL) == explicit
    more = RunSettings("prefsqp_all", "hartmann6", optimizer_options={"radius_scale": 2.0})
    assert more.optimizer_options == {**ALL, "radius_scale": 2.0}
    with pytest.raises(SettingError) as info:
        RunSettings("prefsqp_all", "hartmann6", optimizer_options={"accept_step": "always"})
    assert info.value.field == "optimizer_options.accept_step"
    assert RunSettings("turpbo", "hartmann6").optimizer_options == {}
    assert expand("turpbo", {"batch_size": 2}) == ("turpbo", {"batch_size": 2})


def _bench(tmp: Path, *argv: str) -> dict[str, object]:
    head = ["bench", "--problem", "hartmann6", "--budget", "8", "--out", str(tmp)]
    code = main([*head, "--no-progress", *argv])
    assert code == 0
    (doc,) = [json.loads(p.read_text()) for p in (tmp / "runs").glob("*.json")]
    return doc


def test_preset_runs_bit_identical_to_explicit_options(tmp_path: Path) -> None:
    preset = _bench(tmp_path / "preset", "--algorithm", "prefsqp_all", "--seeds", "1")
    options = [f"--option={k}={v}" for k, v in ALL.items()]
    explicit = _bench(tmp_path / "explicit", "--algorithm", "prefsqp", "--seeds", "1", *options)
    assert preset["settings"] == explicit["settings"]
    assert preset["settings"]["algorithm"] == "prefsqp"  # type: ignore[index]
    assert preset["candidates"] == explicit["candidates"]
    assert preset["answers"] == explicit["answers"]


def test_bench_names_presets_in_options_and_refuses_two_of_one_algorithm(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    per = parse_options(["hybrid_c0.5.step_size=0.4", "batch_size=2"], ["hybrid_c0.5", "sobol"])
    assert per["hybrid_c0.5"]["step_size"] == 0.4
    assert per["sobol"] == {"batch_size": 2}
    with pytest.raises(ValueError, match="'gipbo' is not in --algorithm"):
        parse_options(["gipbo.accept_step=duel"], ["gipbo_gated"])
    head = ["bench", "--problem", "hartmann6", "--algorithm", "prefsqp,prefsqp_all"]
    with pytest.raises(SystemExit) as exit_:
        main([*head, "--out", str(tmp_path), "--no-progress"])
    assert exit_.value.code == 2
    assert "run the same algorithm" in capsys.readouterr().err


def test_spec_entries_name_presets() -> None:
    doc = {
        "schema": "localpbo/experiment/v1",
        "name": "x",
        "seeds": [0],
        "problems": [{"problem": "hartmann6"}],
        "algorithms": [
            {"algorithm": "prefsqp_all"},
            {"algorithm": "prefsqp", "label": "mine", "options": ALL},
        ],
    }
    a, b = parse_spec(doc).runs()
    assert (a.algorithm_label, b.algorithm_label) == ("prefsqp_all", "mine")
    assert a.settings == b.settings
    doc["algorithms"] = [{"algorithm": "prefsqp_all", "options": {"accept_step": "always"}}]
    with pytest.raises(SettingError) as info:
        parse_spec(doc)
    assert info.value.field == "algorithms[0].options.accept_step"


def test_spec_labels_of_presets_are_the_presets() -> None:
    """Wherever a bundled spec uses a preset's label, it runs the preset; every label of a
    ``beyond_*`` spec is an algorithm or a preset, so the evidence's choice can be the
    default."""
    used = set()
    for path in sorted(SPEC_DIR.glob("*.yaml")):
        spec = load_spec(path, validate=False)
        for entry in spec.algorithms:
            if spec.name.startswith(BEYOND_PREFIX):  # each can be the evidence's default
                assert runnable(entry.label), (spec.name, entry.label)
            if entry.label in PRESETS:
                used.add(entry.label)
                preset = PRESETS[entry.label]
                assert (entry.name, entry.options) == (preset.algorithm, dict(preset.options))
    assert used == set(PRESETS)  # every preset is a variant some beyond_* spec runs
