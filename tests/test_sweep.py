"""``localpbo sweep`` on a real local Ray with 2 workers, resume, and ``localpbo report``."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from localpbo_core.cli import main
from localpbo_core.experiments import load_spec
from localpbo_core.report import write_report
from localpbo_core.settings import SettingError
from localpbo_core.sweep import read_run, run_path, select_runs, sweep

ray = pytest.importorskip("ray")


@pytest.fixture(scope="module")
def local_ray():
    """One local Ray with 2 workers for the module (the sweep reuses a running Ray)."""
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False, logging_level="ERROR")
    yield
    ray.shutdown()


@pytest.fixture(scope="module")
def spec():
    return load_spec("tiny")  # Sobol and TuRPBO on Hartmann 6, 8 evaluations, seeds 0-1


@pytest.fixture(scope="module")
def reference(spec, tmp_path_factory) -> Path:
    """The uninterrupted sweep, in-process (no Ray)."""
    out = tmp_path_factory.mktemp("reference")
    result = sweep(spec, out, in_process=True, progress=False)
    assert len(result.finished) == 4 and not result.failed
    return out


def without_timings(doc: dict) -> dict:
    doc = dict(doc)
    doc.pop("optimizer_seconds")
    doc["records"] = [
        {k: v for k, v in r.items() if k != "decision_seconds"} for r in doc["records"]
    ]
    return doc


def assert_same_runs(spec, a: Path, b: Path) -> None:
    for plan in spec.runs():
        assert without_timings(read_run(run_path(a, plan))) == without_timings(
            read_run(run_path(b, plan))
        ), plan.run_id


def test_ray_sweep_equals_in_process(local_ray, spec, reference, tmp_path) -> None:
    result = sweep(spec, tmp_path, progress=False)
    assert sorted(result.finished) == sorted(p.run_id for p in spec.runs())
    assert not result.failed and not result.skipped
    assert_same_runs(spec, tmp_path, reference)
    doc = read_run(run_path(tmp_path, spec.runs()[0]))
    assert doc["run"]["run_id"] == "hartmann6__sobol__seed0"
    assert len(doc["records"]) == 8 and len(doc["candidates"]) == 8


def test_resume_repeats_no_finished_run(local_ray, spec, reference, tmp_path) -> None:
    first = sweep(spec, tmp_path, max_runs=2, progress=False)
    assert len(first.finished) == 2 and len(first.pending) == 2
    stored = {p: (p.stat().st_mtime_ns, p.read_bytes()) for p in (tmp_path / "runs").iterdir()}
    assert len(stored) == 2
    ran: list[str] = []
    second = sweep(spec, tmp_path, progress=False, on_stored=lambda plan: ran.append(plan.run_id))
    assert sorted(second.skipped) == sorted(first.finished)
    assert sorted(ran) == sorted(second.finished) == sorted(first.pending)
    for path, (mtime, data) in stored.items():  # untouched
        assert (path.stat().st_mtime_ns, path.read_bytes()) == (mtime, data)
    assert not [p for p in (tmp_path / "runs").iterdir() if p.name.startswith(".")]
    assert_same_runs(spec, tmp_path, reference)
    third = sweep(spec, tmp_path, progress=False)
    assert not third.finished and len(third.skipped) == 4


def test_workers_use_one_thread(local_ray) -> None:
    @ray.remote(num_cpus=1)
    def threads() -> tuple[int, str | None]:
        import torch

        return torch.get_num_threads(), os.environ.get("OMP_NUM_THREADS")

    assert ray.get(threads.remote()) == (1, "1")


def test_stored_run_with_other_settings_is_refused(spec, reference, tmp_path) -> None:
    plan = spec.runs()[0]
    other = plan.settings.replace(budget=7)
    from localpbo_core.sweep import write_run

    doc = read_run(run_path(reference, plan))
    from localpbo_core.cli import settings_document

    doc["settings"] = settings_document(other)
    write_run(run_path(tmp_path, plan), doc)
    with pytest.raises(SettingError) as info:
        sweep(spec, tmp_path, in_process=True, progress=False)
    assert info.value.field == "--out"


def test_filters_and_dry_run(spec, reference, capsys) -> None:
    assert [r.run_id for r in select_runs(spec, algorithms=["turpbo"], seeds=[1])] == [
        "hartmann6__turpbo__seed1"
    ]
    with pytest.raises(SettingError) as info:
        select_runs(spec, problems=["levy32"])
    assert info.value.field == "--problems"
    assert main(["sweep", "tiny", "--out", str(reference), "--dry-run", "--seeds", "1"]) == 0
    out = capsys.readouterr().out
    assert "hartmann6__turpbo__seed1" in out and "seed0" not in out
    assert "2 finished, 0 will run" in out


def test_report_is_byte_identical(reference, tmp_path) -> None:
    a = write_report([reference], tmp_path / "a")
    b = write_report([reference], tmp_path / "b")
    files = sorted(p.name for p in a.parent.iterdir())
    assert files == sorted(p.name for p in b.parent.iterdir())
    assert "report.md" in files and "curves__tiny__hartmann6.png" in files
    for name in files:
        assert (a.parent / name).read_bytes() == (b.parent / name).read_bytes(), name
    text = a.read_text()
    assert "| sobol | 2 | 8 |" in text and "p (Holm)" in text
