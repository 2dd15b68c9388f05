"""Mid-run checkpoints (:mod:`localpbo_core.checkpoints`): a run stopped and continued from its
checkpoint, in fresh processes, ends with the uninterrupted run's trace bit for bit, for every
algorithm; a checkpoint that cannot continue the run is refused with its reason and the run
starts again; a sweep keeps, lists and continues checkpoints (in-process and on Ray)."""

from __future__ import annotations

import gzip
import json
import os
import random
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import pytest

from localpbo_core.checkpoints import (
    CheckpointedRun,
    CheckpointError,
    read_checkpoint,
    read_header,
)
from localpbo_core.loop import run_session
from localpbo_core.optimizers import available_optimizers
from localpbo_core.run_documents import trace_document
from localpbo_core.session import Session
from localpbo_core.settings import RunSettings
from localpbo_core.sweep import (
    _worth_starting,
    checkpoint_path,
    format_dry_run,
    read_run,
    run_path,
    sweep,
)

BUDGET = 30

CHILD = """
import json, os, sys
from pathlib import Path
from localpbo_core import checkpoints
from localpbo_core.checkpoints import CheckpointedRun
from localpbo_core.run_documents import trace_document
from localpbo_core.settings import RunSettings

settings = RunSettings(**json.loads(sys.argv[1]))
path, out, stop_after = Path(sys.argv[2]), Path(sys.argv[3]), int(sys.argv[4])
write = checkpoints.write_checkpoint

def write_then_die(target, header, state):
    write(target, header, state)
    if stop_after and header["evaluations"] >= stop_after:
        os.kill(os.getpid(), 9)  # killed right after a checkpoint, as SIGKILL from outside

checkpoints.write_checkpoint = write_then_die
every = float(os.environ.get("CHECKPOINT_EVERY", "1e-9"))
def discarded(error):
    print("DISCARDED", error.reason)

done = CheckpointedRun(settings, path, every, on_discarded=discarded).run()
doc = trace_document(settings, done.trace)
doc["segments"] = done.segments
out.write_text(json.dumps(doc))
"""


def _settings(algorithm: str, **extra: Any) -> RunSettings:
    return RunSettings(
        algorithm=algorithm, problem="hartmann6", seed=3, budget=BUDGET, initial_design=2, **extra
    )


def _settings_args(settings: RunSettings) -> str:
    from localpbo_core.run_documents import settings_document

    return json.dumps(settings_document(settings))


def _child(
    settings: RunSettings, path: Path, out: Path, stop_after: int, env: dict[str, str] | None = None
) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [
            sys.executable,
            "-c",
            CHILD,
            _settings_args(settings),
            str(path),
            str(out),
            str(stop_after),
        ],
        capture_output=True,
        text=True,
        timeout=600,
        env={**os.environ, **(env or {})},
    )


def _without_seconds(doc: dict[str, Any]) -> dict[str, Any]:
    """A trace document without the measured optimizer seconds (the only part that may
    differ between two runs of the same settings)."""
    doc = json.loads(json.dumps(doc))
    doc.pop("segments", None)
    for record in doc["records"]:
        record.pop("decision_seconds")
    return doc


def _uninterrupted(settings: RunSettings) -> dict[str, Any]:
    return _without_seconds(trace_document(settings, run_session(Session(settings))))


@pytest.mark.parametrize("algorithm", available_optimizers())
def test_a_run_killed_and_continued_twice_ends_as_the_uninterrupted_run(
    algorithm: str, tmp_path: Path
) -> None:
    """Killed after checkpoints at two random evaluations, continued each time in a fresh
    process: the same candidates, values, answers and records, bit for bit."""
    settings = _settings(algorithm)
    reference = _uninterrupted(settings)
    rng = random.Random(f"checkpoints-{algorithm}")
    first = rng.randint(3, 10)
    second = rng.randint(first + 1, 18)
    path, out = tmp_path / "run.ckpt.gz", tmp_path / "run.json"
    kept = []
    for stop_after in (first, second):
        killed = _child(settings, path, out, stop_after)
        assert killed.returncode == -signal.SIGKILL, killed.stderr[-2000:]
        kept.append(read_header(path)["evaluations"])
        assert stop_after <= kept[-1] < BUDGET  # the first step boundary after it
    done = _child(settings, path, out, 0)
    assert done.returncode == 0, done.stderr[-2000:]
    assert "DISCARDED" not in done.stdout
    doc = json.loads(out.read_text())
    assert [s["evaluations"] for s in doc["segments"]] == [
        [1, kept[0]],
        [kept[0] + 1, kept[1]],
        [kept[1] + 1, BUDGET],
    ]
    assert _without_seconds(doc) == reference


def test_sigkill_at_random_times_never_leaves_a_checkpoint_that_breaks_the_run(
    tmp_path: Path,
) -> None:
    """SIGKILL from outside at random moments (mid-step or mid-write): every continuation
    reads the last whole checkpoint and the run ends as the uninterrupted one."""
    settings = _settings("turpbo")
    reference = _uninterrupted(settings)
    path, out = tmp_path / "run.ckpt.gz", tmp_path / "run.json"
    rng = random.Random(7)
    kills = 0
    for _ in range(30):
        proc = subprocess.Popen(
            [sys.executable, "-c", CHILD, _settings_args(settings), str(path), str(out), "0"],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        before = read_header(path)["evaluations"] if path.exists() else 0
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline and proc.poll() is None:  # wait for progress
            if path.exists() and read_header(path)["evaluations"] > before:
                break
            time.sleep(0.02)
        time.sleep(rng.uniform(0.0, 0.4))
        if proc.poll() is None:
            proc.send_signal(signal.SIGKILL)
            kills += 1
        stdout, stderr = proc.communicate(timeout=600)
        assert "DISCARDED" not in stdout, stdout
        if proc.returncode == 0:
            break
        assert proc.returncode == -signal.SIGKILL, stderr[-2000:]
    assert kills >= 2 and out.exists()
    assert _without_seconds(json.loads(out.read_text())) == reference
    leftovers = [p.name for p in tmp_path.iterdir() if p.name.endswith(".tmp")]
    assert len(leftovers) <= 1  # at most the write the last kill cut short


def _checkpoint_at(settings: RunSettings, path: Path, evaluations: int) -> None:
    done = _child(settings, path, path.with_suffix(".json"), evaluations)
    assert done.returncode == -signal.SIGKILL, done.stderr[-2000:]


def test_a_checkpoint_of_other_settings_or_code_or_damaged_is_refused_with_its_reason(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    settings = _settings("sobol")
    path = tmp_path / "run.ckpt.gz"
    _checkpoint_at(settings, path, 10)
    assert len(read_checkpoint(path, settings).state.trace.records) == 10

    with pytest.raises(CheckpointError) as other:
        read_checkpoint(path, _settings("sobol", noise_fraction=0.2))
    assert other.value.reason == "holds a run of other settings"

    from localpbo_core import checkpoints

    monkeypatch.setattr(
        checkpoints, "code_digests", lambda a: {"digest": "0", "algorithm_digest": "0"}
    )
    with pytest.raises(CheckpointError) as code:
        read_checkpoint(path, settings)
    assert code.value.reason.startswith("made by other code")
    monkeypatch.undo()

    damaged = tmp_path / "damaged.ckpt.gz"
    damaged.write_bytes(gzip.compress(gzip.decompress(path.read_bytes())[:-200]))
    with pytest.raises(CheckpointError) as cut:
        read_checkpoint(damaged, settings)
    assert cut.value.reason.startswith("state unreadable")

    for name, data in (("empty", b""), ("text", b"not gzip"), ("json", gzip.compress(b"{}\n"))):
        foreign = tmp_path / f"{name}.ckpt.gz"
        foreign.write_bytes(data)
        with pytest.raises(CheckpointError):
            read_checkpoint(foreign, settings)
    huge = tmp_path / "huge.ckpt.gz"
    huge.write_bytes(gzip.compress(b"x" * (2 << 20)))  # no header line within the bound
    with pytest.raises(CheckpointError) as long_line:
        read_header(huge)
    assert "not a localpbo/checkpoint/v1 file" in long_line.value.reason


def test_a_refused_checkpoint_is_reported_and_the_run_starts_again(tmp_path: Path) -> None:
    settings = _settings("sobol")
    path = tmp_path / "run.ckpt.gz"
    _checkpoint_at(settings, path, 10)
    other = _settings("sobol", noise_fraction=0.2)
    seen: list[CheckpointError] = []
    done = CheckpointedRun(other, path, 1e9, on_discarded=seen.append).run()
    assert [e.reason for e in seen] == ["holds a run of other settings"]
    assert done.segments == []
    doc = _without_seconds(trace_document(other, done.trace))
    assert doc == _uninterrupted(other)


def test_checkpoints_are_written_only_after_the_interval(tmp_path: Path) -> None:
    settings = _settings("sobol")
    path = tmp_path / "run.ckpt.gz"
    run = CheckpointedRun(settings, path, 3600.0)
    run.run()
    assert run.written == 0 and not path.exists()
    with pytest.raises(Exception, match="checkpoint-every"):
        CheckpointedRun(settings, path, 0.0)


def test_worth_starting_keeps_progress_with_checkpoints(tmp_path: Path) -> None:
    """Under ``--time-limit``: a run that fits starts; one that does not starts only with
    checkpoints and at least one interval left; a checkpoint's seconds count as done."""
    assert _worth_starting(100.0, 90.0, None, None)
    assert not _worth_starting(100.0, 200.0, None, None)
    assert _worth_starting(700.0, 9000.0, None, 600.0)
    assert not _worth_starting(500.0, 9000.0, None, 600.0)
    path = tmp_path / "run.ckpt.gz"
    _checkpoint_at(_settings("sobol"), path, 10)
    seconds = read_header(path)["run_seconds"]
    assert _worth_starting(100.0, 100.0 + seconds, path, None)
    assert not _worth_starting(100.0, 100.0 + seconds + 1.0, path, None)


BUDGET_SPEC = 60
SPEC = """
schema: localpbo/experiment/v1
name: ckpt
paper: none (test)
description: TuRPBO on Hartmann 6, long enough to be stopped.
seeds: 0-1
settings: {initial_design: 2, budget: 60, noise_fraction: 0.1}
problems:
  - problem: hartmann6
algorithms:
  - {algorithm: turpbo, options: {num_raw_samples: 64, num_restarts: 2, num_features: 256}}
"""


@pytest.fixture(scope="module")
def ckpt_spec(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("spec") / "ckpt.yaml"
    path.write_text(SPEC)
    return path


@pytest.fixture(scope="module")
def ckpt_reference(ckpt_spec: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    from localpbo_core.experiments import load_spec

    out = tmp_path_factory.mktemp("reference")
    result = sweep(load_spec(str(ckpt_spec)), out, in_process=True, progress=False)
    assert len(result.finished) == 2
    return out


def _assert_as_reference(out: Path, reference: Path, plan: Any) -> None:
    """The run of ``plan`` stored in ``out`` is the reference sweep's, but for its seconds."""
    assert _stored_trace(run_path(out, plan)) == _stored_trace(run_path(reference, plan))


def _stored_trace(path: Path) -> dict[str, Any]:
    doc = read_run(path)
    return _without_seconds(
        {k: doc[k] for k in ("schema", "settings", "candidates", "answers", "records")}
    )


def test_a_stopped_sweep_continues_from_the_checkpoints(
    ckpt_spec: Path, ckpt_reference: Path, tmp_path: Path
) -> None:
    """``localpbo sweep`` stopped by SIGTERM (as its ``--time-limit`` stops it) mid-run: the
    run's checkpoint is listed, shown by ``--dry-run``, and the same command continues it to
    the reference run."""
    from localpbo_core.experiments import load_spec

    plans = load_spec(str(ckpt_spec)).runs()
    cmd = [
        sys.executable, "-m", "localpbo_core.cli", "sweep", str(ckpt_spec), "--out", str(tmp_path),
        "--in-process", "--no-progress", "--checkpoint-every", "0.001s", "--seeds", "0",
    ]  # fmt: skip
    ckpt = checkpoint_path(tmp_path, plans[0])
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 300
    while time.monotonic() < deadline and proc.poll() is None:
        if ckpt.exists() and read_header(ckpt)["evaluations"] >= 10:
            break
        time.sleep(0.01)
    proc.send_signal(signal.SIGTERM)
    stdout, stderr = proc.communicate(timeout=300)
    assert proc.returncode == 130, stderr[-2000:]
    kept = read_header(ckpt)["evaluations"]
    assert 10 <= kept < BUDGET_SPEC
    assert f"CHECKPOINT {plans[0].run_id}: {kept} evaluations kept" in stdout
    assert not run_path(tmp_path, plans[0]).exists()
    listing = format_dry_run(tmp_path, plans[:1], None)
    assert f"(continues its checkpoint at {kept})" in listing
    assert "continues" not in format_dry_run(tmp_path, plans[:1], None, checkpoints=False)

    done = subprocess.run(cmd, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr[-2000:]
    assert f"CONTINUED {plans[0].run_id}: from its checkpoint at {kept} evaluations" in done.stdout
    assert not ckpt.exists()
    stored = read_run(run_path(tmp_path, plans[0]))
    parts = stored["checkpoints"]["segments"]
    assert [p["evaluations"] for p in parts] == [[1, kept], [kept + 1, BUDGET_SPEC]]
    assert stored["run_seconds"] == pytest.approx(sum(p["run_seconds"] for p in parts))
    assert stored["cpu_seconds"] == pytest.approx(sum(p["cpu_seconds"] for p in parts))
    _assert_as_reference(tmp_path, ckpt_reference, plans[0])


def test_without_checkpoints_a_sweep_neither_writes_nor_reads_them(
    ckpt_spec: Path, ckpt_reference: Path, tmp_path: Path
) -> None:
    from localpbo_core.experiments import load_spec

    spec = load_spec(str(ckpt_spec))
    plans = spec.runs()
    path = checkpoint_path(tmp_path, plans[0])
    _checkpoint_at(plans[0].settings, path, 12)
    result = sweep(
        spec, tmp_path, plans[:1], in_process=True, progress=False, checkpoint_every=None
    )
    assert result.finished == [plans[0].run_id] and result.resumed == {}
    assert "checkpoints" not in read_run(run_path(tmp_path, plans[0]))
    assert not path.exists()  # the stored run makes it useless; it is removed
    _assert_as_reference(tmp_path, ckpt_reference, plans[0])


def test_a_ray_sweep_continues_a_checkpoint(
    ckpt_spec: Path, ckpt_reference: Path, tmp_path: Path
) -> None:
    """The Ray worker reads (and would write) the checkpoint at the path the driver names."""
    from localpbo_core.experiments import load_spec

    spec = load_spec(str(ckpt_spec))
    plans = spec.runs()
    _checkpoint_at(plans[1].settings, checkpoint_path(tmp_path, plans[1]), 17)
    result = sweep(spec, tmp_path, plans[1:], workers=1, progress=False)
    assert result.finished == [plans[1].run_id] and result.resumed == {plans[1].run_id: 17}
    _assert_as_reference(tmp_path, ckpt_reference, plans[1])


def test_the_results_page_lists_the_checkpoints_under_way(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The Coverage section's table (:func:`checkpoint_table`): each checkpoint's spec, run,
    evaluations kept, CPU seconds and whether today's code continues it; a damaged one says
    so; none, no table."""
    from localpbo_core import checkpoints
    from localpbo_core.experiments.coverage import checkpoint_table

    assert checkpoint_table([tmp_path]) == []
    path = tmp_path / "myspec" / "checkpoints" / "hartmann6__sobol__seed3.ckpt.gz"
    _checkpoint_at(_settings("sobol"), path, 10)
    (path.parent / "broken__seed0.ckpt.gz").write_bytes(b"not gzip")
    header = read_header(path)
    cpu = f"{header['cpu_seconds']:.0f}"
    table = checkpoint_table([tmp_path, tmp_path / "missing"])
    assert table[4:6] == [
        "| myspec | broken__seed0 | unreadable | | no |",
        f"| myspec | hartmann6__sobol__seed3 | 10 of 30 | {cpu} | yes |",
    ]
    monkeypatch.setattr(
        checkpoints, "code_digests", lambda a: {"digest": "0", "algorithm_digest": "0"}
    )
    assert checkpoint_table([tmp_path])[5].endswith("| no: other code |")
