"""``localpbo sweep`` on a real local Ray with 2 workers, resume, and ``localpbo report``."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from localpbo_core import ray_cleanup
from localpbo_core.cli import main
from localpbo_core.experiments import load_spec
from localpbo_core.provenance import CPU_FLAGS, platform_block
from localpbo_core.report import write_report
from localpbo_core.run_documents import settings_document
from localpbo_core.settings import SettingError
from localpbo_core.sweep import (
    LOOPBACK_ONLY_ENV,
    effective_settings,
    format_dry_run,
    read_run,
    run_path,
    select_runs,
    start_ray,
    stop_ray,
    sweep,
)

os.environ.setdefault(LOOPBACK_ONLY_ENV, "0")  # before Ray is imported, as the sweep does
ray = pytest.importorskip("ray")


@pytest.fixture(scope="module")
def local_ray():
    """The sweep's embedded Ray with 2 workers for the module (the sweep reuses it)."""
    assert start_ray(None, 2)
    yield
    stop_ray()


def test_embedded_ray_listens_on_loopback_only(local_ray) -> None:
    psutil = pytest.importorskip("psutil")
    ours = {os.getpid()} | {p.pid for p in psutil.Process().children(recursive=True)}
    listening = [
        c
        for c in psutil.net_connections(kind="tcp")
        if c.status == psutil.CONN_LISTEN and c.pid in ours
    ]
    assert listening  # GCS, raylet, workers
    assert all(c.laddr.ip in ("127.0.0.1", "::1", "::ffff:127.0.0.1") for c in listening), [
        (c.pid, c.laddr) for c in listening
    ]


@pytest.fixture(scope="module")
def spec(tiny_spec):
    return tiny_spec


@pytest.fixture(scope="module")
def reference(tiny_reference) -> Path:
    return tiny_reference


def without_timings(doc: dict) -> dict:
    """The run's trace: without its timings, and without its ``code`` block, whose commit
    changes when somebody commits while the test runs (:func:`assert_same_runs` compares
    the digests)."""
    doc = dict(doc)
    doc.pop("optimizer_seconds")
    assert 0 < doc.pop("cpu_seconds") and 0 < doc.pop("run_seconds")
    code = doc.pop("code")
    assert set(code) == {"digest", "algorithm_digest", "commit", "dirty"}
    doc["records"] = [
        {k: v for k, v in r.items() if k != "decision_seconds"} for r in doc["records"]
    ]
    return doc


def assert_same_runs(spec, a: Path, b: Path) -> None:
    for plan in spec.runs():
        one, other = read_run(run_path(a, plan)), read_run(run_path(b, plan))
        assert without_timings(one) == without_timings(other), plan.run_id
        digests = ("digest", "algorithm_digest")
        assert [one["code"][k] for k in digests] == [other["code"][k] for k in digests]


def test_stored_runs_say_what_they_ran(spec, reference) -> None:
    """Each stored run carries its settings completed by the defaults: every option of the
    algorithm and the budget it ran."""
    from localpbo_core.optimizers import optimizer_defaults

    for plan in spec.runs():
        doc = read_run(run_path(reference, plan))
        effective = doc["effective_settings"]
        assert effective["budget"] == len(doc["candidates"]) == len(doc["records"])
        assert set(effective["optimizer_options"]) == set(
            optimizer_defaults(plan.settings.algorithm)
        ) - set(doc["settings"])
        assert {k: v for k, v in effective.items() if k not in ("budget", "optimizer_options")} == {
            k: v for k, v in doc["settings"].items() if k not in ("budget", "optimizer_options")
        }
        assert doc["platform"] == platform_block()


def test_platform_block_names_the_kernels_a_run_went_through() -> None:
    """The platform block holds this process's torch kernel level and threads and the
    installed versions of the numerical libraries."""
    import importlib.metadata

    import numpy
    import torch

    block = platform_block()
    assert block["cpu_capability"] == torch.backends.cpu.get_cpu_capability()
    assert block["torch_threads"] == torch.get_num_threads()
    assert block["libraries"]["numpy"] == numpy.__version__
    assert block["libraries"]["torch"] == importlib.metadata.version("torch")
    assert {"botorch", "gpytorch", "scipy"} <= set(block["libraries"])
    assert block["cpu"] and block["machine"] and block["python"].startswith("3.")
    assert set(block["cpu_flags"].split()) <= set(CPU_FLAGS)
    if block["cpu_capability"].startswith("AVX512"):
        assert "avx512f" in block["cpu_flags"].split()


def test_ray_sweep_equals_in_process(local_ray, spec, reference, tmp_path) -> None:
    result = sweep(spec, tmp_path, progress=False)
    assert sorted(result.finished) == sorted(p.run_id for p in spec.runs())
    assert not result.failed and not result.skipped
    assert_same_runs(spec, tmp_path, reference)
    doc = read_run(run_path(tmp_path, spec.runs()[0]))
    assert doc["run"]["run_id"] == "hartmann6__sobol__seed0"
    assert len(doc["records"]) == 8 and len(doc["candidates"]) == 8


def test_ray_sweep_passes_over_runs_another_sweep_holds(local_ray, spec, tmp_path) -> None:
    from localpbo_core.run_claims import try_claim

    plans = spec.runs()
    held = try_claim(tmp_path, plans[1].run_id)
    result = sweep(spec, tmp_path, progress=False)
    assert [p.name for p in (tmp_path / ".claims").iterdir()] == [f"{plans[1].run_id}.claim"]
    held.release()
    assert list(result.elsewhere) == [plans[1].run_id] and len(result.finished) == 3
    assert not run_path(tmp_path, plans[1]).exists()


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
    from localpbo_core.run_documents import settings_document

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


def test_the_summary_counts_runs_in_words(spec, reference, tmp_path, capsys) -> None:
    """The summary line says "1 run finished" for one run and "N runs" otherwise."""
    import shutil

    shutil.copytree(reference / "runs", tmp_path / "runs")
    (tmp_path / "runs" / "hartmann6__sobol__seed1.json.gz").unlink()
    assert main(["sweep", "tiny", "--out", str(tmp_path), "--in-process", "--no-progress"]) == 0
    out = capsys.readouterr().out
    assert "tiny: 1 run finished, 3 already stored, 0 failed, 0 left" in out
    assert main(["sweep", "tiny", "--out", str(tmp_path), "--in-process", "--no-progress"]) == 0
    assert "tiny: 0 runs finished, 4 already stored" in capsys.readouterr().out


def _rewrite(path: Path, change) -> None:
    """Store the run at ``path`` again after ``change(doc)``."""
    from localpbo_core.sweep import write_run

    doc = read_run(path)
    change(doc)
    write_run(path, doc)


def test_rerun_changed_replaces_only_runs_of_older_code(spec, reference, tmp_path) -> None:
    """``--rerun-changed`` runs again a run whose algorithm digest is not today's and one
    without a code version, keeps current ones, keeps the old file until the new one is
    stored (an interrupted re-run continues), each re-run says what it replaced (``replaced``:
    old code, shared candidates, same duel answers, old finals), and the re-runs equal the
    reference runs."""
    import shutil

    from localpbo_core.sweep import write_run

    out = tmp_path / "results" / "tiny"
    shutil.copytree(reference, out)
    ids = [p.run_id for p in spec.runs()]
    changed, unknown = ids[0], ids[-1]

    def older(doc) -> None:  # older code, which parted from today's at the fourth candidate
        doc["code"].update(algorithm_digest="0")
        doc["candidates"][3]["native"][0] += 0.25

    def unknown_code(doc) -> None:  # no code or platform version; one duel went the other way
        doc.pop("code")
        doc.pop("platform")
        answer = doc["answers"][-1]
        answer["winner"] = answer["first"] + answer["second"] - answer["winner"]

    _rewrite(out / "runs" / f"{changed}.json.gz", older)
    _rewrite(out / "runs" / f"{unknown}.json.gz", unknown_code)
    before = {i: (out / "runs" / f"{i}.json.gz").read_bytes() for i in ids}

    assert main(["sweep", "tiny", "--out", str(out), "--dry-run", "--rerun-changed"]) == 0
    plain = sweep(spec, out, in_process=True, progress=False)
    assert not plain.finished and len(plain.skipped) == 4

    def stop_after_first(plan) -> None:
        raise KeyboardInterrupt

    first = sweep(
        spec, out, in_process=True, progress=False, rerun_changed=True, on_stored=stop_after_first
    )
    assert first.interrupted and first.rerun == first.finished == [changed]
    assert first.pending == [unknown]
    assert (out / "runs" / f"{unknown}.json.gz").read_bytes() == before[unknown]
    second = sweep(spec, out, in_process=True, progress=False, rerun_changed=True)
    assert second.rerun == second.finished == [unknown]
    assert sorted(second.skipped) == sorted(set(ids) - {unknown})
    for i in set(ids) - {changed, unknown}:
        assert (out / "runs" / f"{i}.json.gz").read_bytes() == before[i]
    # each re-run says what it replaced
    for run_id, code, identical, gap, answers in (
        (changed, "0", 3, 0.25, True),
        (unknown, None, None, 0.0, False),
    ):
        path = out / "runs" / f"{run_id}.json.gz"
        doc = read_run(path)
        replaced = doc.pop("replaced")
        write_run(path, doc)
        reference_doc = read_run(reference / "runs" / f"{run_id}.json.gz")
        n = len(reference_doc["candidates"])
        assert replaced == {
            "commit": None if code is None else reference_doc["code"]["commit"],
            "algorithm_digest": code,
            "stored_by_commit": False,
            "candidates": n,
            "identical": n if identical is None else identical,
            "first_gap": pytest.approx(gap, abs=1e-15),
            "same_answers": answers,
            "same_platform": None if code is None else True,
            "best_seen": reference_doc["records"][-1]["best_seen"],
            "cumulative": reference_doc["records"][-1]["cumulative"],
        }, run_id
    assert_same_runs(spec, out, reference)
    third = sweep(spec, out, in_process=True, progress=False, rerun_changed=True)
    assert not third.finished and len(third.skipped) == 4


def test_rerun_changed_keeps_runs_of_equivalent_or_dated_code(spec, reference, tmp_path) -> None:
    """A run of older code that a recorded re-run showed equivalent
    (``equivalent_code.json``) and a run without a code block that ``stored_code.json`` dates
    to today's code (both in the results folder, the parent of ``--out``) are not re-run; the
    dry run says which are."""
    import json
    import shutil

    from localpbo_core.provenance import code_block

    results = tmp_path / "results"
    out = results / "tiny"
    shutil.copytree(reference, out)
    ids = [p.run_id for p in spec.runs()]
    old, undated = ids[0], ids[-1]
    algorithm = read_run(out / "runs" / f"{old}.json.gz")["settings"]["algorithm"]
    undated_alg = read_run(out / "runs" / f"{undated}.json.gz")["settings"]["algorithm"]
    _rewrite(out / "runs" / f"{old}.json.gz", lambda d: d["code"].update(algorithm_digest="0"))
    _rewrite(out / "runs" / f"{undated}.json.gz", lambda d: d.pop("code"))
    text = format_dry_run(out, spec.runs(), None, rerun_changed=True)
    assert "2 finished, 0 will run, 2 will rerun" in text
    today = code_block(algorithm)["algorithm_digest"]
    entry = {"algorithm": algorithm, "from": "0", "to": today, "candidates": 8, "identical": 8}
    (results / "equivalent_code.json").write_text(json.dumps([entry]))
    (results / "stored_code.json").write_text(
        json.dumps(
            {
                "commits": {
                    "c0": {
                        "digest": "d",
                        "algorithms": {undated_alg: code_block(undated_alg)["algorithm_digest"]},
                    }
                },
                "runs": {f"tiny/runs/{undated}.json.gz": "c0"},
            }
        )
    )
    text = format_dry_run(out, spec.runs(), None, rerun_changed=True)
    assert "4 finished, 0 will run, 0 will rerun" in text
    result = sweep(spec, out, in_process=True, progress=False, rerun_changed=True)
    assert not result.finished and len(result.skipped) == 4


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


def test_interrupted_sweep_keeps_what_finished_and_continues(spec, reference, tmp_path) -> None:
    def stop_after_first(plan) -> None:
        raise KeyboardInterrupt

    first = sweep(spec, tmp_path, in_process=True, progress=False, on_stored=stop_after_first)
    assert first.interrupted and len(first.finished) == 1 and len(first.pending) == 3
    assert [p.name for p in (tmp_path / "runs").iterdir()] == [f"{first.finished[0]}.json.gz"]
    second = sweep(spec, tmp_path, in_process=True, progress=False)
    assert not second.interrupted and second.skipped == first.finished
    assert sorted(second.finished) == sorted(first.pending)
    assert_same_runs(spec, tmp_path, reference)


SWEEP_RUNS = 4
"""Runs of the real sweep process the signal tests stop: more than its two workers take at
once, so a signal after the first stored run lands mid-sweep."""


def _sweep_cmd(out: Path) -> list[str]:
    cmd = [sys.executable, "-m", "localpbo_core.cli", "sweep", "synthetic", "--out", str(out)]
    cmd += ["--problems", "hartmann6", "--algorithms", "turpbo", "--seeds", f"0-{SWEEP_RUNS - 1}"]
    return [*cmd, "--workers", "2", "--no-progress"]


def _start_sweep(out: Path) -> tuple[subprocess.Popen[str], Path]:
    """A real ``localpbo sweep`` process, once it has stored a run (mid-sweep), and its
    embedded Ray's private folder."""
    proc = subprocess.Popen(
        _sweep_cmd(out),
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),  # as in a terminal
    )
    runs = out / "runs"
    deadline = time.monotonic() + 300  # a loaded machine: the first run may take minutes
    while not (runs.is_dir() and any(runs.glob("*.json.gz"))):  # one run stored: mid-sweep
        assert proc.poll() is None and time.monotonic() < deadline, proc.communicate()
        time.sleep(0.1)
    folders = list(ray_cleanup.PARENT.glob(f"{ray_cleanup.PREFIX}{proc.pid}-*"))
    assert len(folders) == 1, folders  # the embedded Ray runs in its private folder
    assert ray_cleanup.holders(folders[0])  # its processes hold their logs there
    assert not list(Path("/tmp/ray").glob(f"session_*_{proc.pid}"))  # not in Ray's default
    return proc, folders[0]


def _watchdogs(pid: int) -> list[int]:
    """Running watchdog processes of driver ``pid``."""
    found = []
    for entry in Path("/proc").iterdir():
        try:
            cmdline = (entry / "cmdline").read_bytes().split(b"\0")
        except OSError:
            continue
        if b"localpbo_core.ray_cleanup" in cmdline and str(pid).encode() in cmdline:
            found.append(int(entry.name))
    return found


def _left_behind(proc: subprocess.Popen[str], folder: Path, within_s: float) -> list[str]:
    """What of the sweep's Ray is still there after ``within_s`` seconds (empty: nothing)."""
    deadline = time.monotonic() + within_s
    while True:
        left = [f"pid {pid} holds {folder}" for pid in ray_cleanup.holders(folder)]
        left += [f"watchdog {pid}" for pid in _watchdogs(proc.pid)]
        left += [str(folder)] if folder.exists() else []
        if not left or time.monotonic() > deadline:
            return left
        time.sleep(0.2)


@pytest.mark.timeout(1500)  # two sweeps of TuRPBO runs on a machine that may be loaded
@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM])
def test_ctrl_c_and_sigterm_stop_a_ray_sweep(signum, tmp_path) -> None:
    """A real ``localpbo sweep`` process: the signal stops it within seconds, exit 130, the
    summary printed, every stored run complete, no Ray process and no Ray folder left (the
    watchdog gone too); running it again finishes the rest."""
    out = tmp_path / "out"
    proc, folder = _start_sweep(out)
    proc.send_signal(signum)
    sent = time.monotonic()
    stdout, stderr = proc.communicate(timeout=60)
    assert time.monotonic() - sent < 30
    assert proc.returncode == 130, stderr
    assert "Traceback" not in stderr and "interrupted: the same command continues" in stderr
    assert not ray_cleanup.holders(folder) and not folder.exists()  # at the driver's exit
    assert _left_behind(proc, folder, 10.0) == []
    finished = sorted((out / "runs").glob("*.json.gz"))
    assert 1 <= len(finished) < SWEEP_RUNS and "left" in stdout
    for path in finished:
        assert read_run(path)["run"]["seed"] in range(SWEEP_RUNS)
    again = subprocess.run(_sweep_cmd(out), capture_output=True, text=True, timeout=900)
    assert again.returncode == 0, again.stderr
    assert f"{len(finished)} already stored" in again.stdout
    assert len(list((out / "runs").glob("*.json.gz"))) == SWEEP_RUNS


@pytest.mark.timeout(900)
def test_the_time_limit_stops_a_ray_sweep_cleanly(tmp_path) -> None:
    """``--time-limit`` shorter than the runs: the Ray sweep stops them as on SIGTERM (exit
    130, the limit named), and nothing of its Ray nor any claim stays behind."""
    cmd = [sys.executable, "-m", "localpbo_core.cli", "sweep", "synthetic", "--out", str(tmp_path)]
    cmd += ["--problems", "levy32", "--algorithms", "turpbo", "--seeds", "0-2", "--workers", "2"]
    proc = subprocess.Popen(
        [*cmd, "--no-progress", "--time-limit", "20s"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    out, err = proc.communicate(timeout=600)
    assert proc.returncode == 130, (out, err)
    assert "--time-limit 20s reached: the runs under way were stopped" in out
    assert "0 runs finished" in out and "3 left" in out
    assert not list(ray_cleanup.PARENT.glob(f"{ray_cleanup.PREFIX}{proc.pid}-*"))
    deadline = time.monotonic() + 15  # the watchdog ends once it sees the driver gone
    while _watchdogs(proc.pid) and time.monotonic() < deadline:
        time.sleep(0.2)
    assert not _watchdogs(proc.pid)
    assert not list((tmp_path / ".claims").iterdir())


@pytest.mark.parametrize("delay_s", [0.0, 2.0])
def test_sigterm_while_ray_starts_stops_the_sweep_cleanly(delay_s, tmp_path) -> None:
    """SIGTERM while the embedded Ray is still starting (its private folder made, ``ray.init``
    under way, whose own handler turns SIGTERM into ``sys.exit``): exit 130 without a
    traceback, nothing of Ray left."""
    proc = subprocess.Popen(
        _sweep_cmd(tmp_path / "out"), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
    )
    deadline = time.monotonic() + 60
    while not (folders := list(ray_cleanup.PARENT.glob(f"{ray_cleanup.PREFIX}{proc.pid}-*"))):
        assert proc.poll() is None and time.monotonic() < deadline, proc.communicate()
        time.sleep(0.02)
    time.sleep(delay_s)
    proc.send_signal(signal.SIGTERM)
    _, stderr = proc.communicate(timeout=60)
    assert proc.returncode == 130, stderr
    assert "Traceback" not in stderr and "interrupted" in stderr
    assert _left_behind(proc, folders[0], 10.0) == []


_SIGTERM_DISPOSITION = """
import ctypes, json, signal, sys
from localpbo_core import sweep

libc = ctypes.CDLL(None)


def disposition() -> int:
    # glibc's struct sigaction starts with the handler's address; 256 bytes hold all of it
    old = ctypes.create_string_buffer(256)
    assert libc.sigaction(signal.SIGTERM, None, old) == 0
    return int.from_bytes(old.raw[:8], "little")


signal.signal(signal.SIGTERM, lambda signum, frame: None)
before = disposition()
sweep.start_ray(None, 1, keep_sigterm_handler=sys.argv[1] == "keep")
after = disposition()
sweep.stop_ray()
print(json.dumps({"kept": before == after}))
"""


@pytest.mark.parametrize("keep", [True, False])
def test_ray_init_leaves_the_os_sigterm_handler_in_place(keep, tmp_path) -> None:
    """With ``keep_sigterm_handler``, ``ray.init`` leaves the process's SIGTERM handler as it is,
    down to the C handler the operating system calls (read back with ``sigaction``): none of
    Ray's (its Python ``sys.exit`` handler, its C++ failure handler that aborts the process 3 s
    after a SIGTERM) gets a SIGTERM that lands while Ray starts. Without it, both are there, so
    the check can tell."""
    script = tmp_path / "disposition.py"
    script.write_text(_SIGTERM_DISPOSITION)
    done = subprocess.run(
        [sys.executable, str(script), "keep" if keep else "ray"],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == 0, done.stderr
    assert json.loads(done.stdout.strip().splitlines()[-1]) == {"kept": keep}


def test_sigkill_of_the_driver_leaves_nothing_once_its_watchdog_has_run(tmp_path) -> None:
    """SIGKILL gives the driver no chance to stop Ray; its watchdog stops every process of
    the session (Ray's agents ignore SIGTERM: SIGKILL after 0.5 s) and removes the folder.
    Measured here with both cores busy: nothing left 2-10 s after the kill; allowed: 30 s."""
    proc, folder = _start_sweep(tmp_path / "out")
    assert _watchdogs(proc.pid)
    proc.kill()
    proc.communicate(timeout=30)
    assert _left_behind(proc, folder, 30.0) == []


def test_folders_of_killed_drivers_are_cleaned_by_the_next_sweep(tmp_path) -> None:
    """Driver and watchdog both SIGKILLed: the next embedded Ray start finds the folder of a
    driver that no longer runs, stops what holds it (a process ignoring SIGTERM too) and
    removes it; the folder of a running driver is left alone."""
    dead = subprocess.Popen(["true"])
    dead.wait()
    stale = tmp_path / f"{ray_cleanup.PREFIX}{dead.pid}-abc123"
    alive = tmp_path / f"{ray_cleanup.PREFIX}{os.getpid()}-abc123"
    stale.mkdir()
    alive.mkdir()
    stubborn = subprocess.Popen(
        [
            sys.executable,
            "-c",
            "import signal, sys, time; signal.signal(signal.SIGTERM, signal.SIG_IGN); "
            "log = open(sys.argv[1], 'w'); print('up', flush=True); time.sleep(120)",
            str(stale / "agent.log"),
        ],
        stdout=subprocess.PIPE,
        text=True,
    )
    assert stubborn.stdout is not None and stubborn.stdout.readline() == "up\n"
    assert ray_cleanup.holders(stale) == [stubborn.pid]
    assert ray_cleanup.clean_stale(tmp_path) == [stale]
    assert stubborn.wait(timeout=10) == -signal.SIGKILL
    assert not stale.exists() and alive.is_dir()


def test_reuse_copies_identical_runs_and_computes_the_rest(
    spec, reference, tmp_path, monkeypatch, capsys
) -> None:
    """A second spec shares the Sobol runs of ``tiny`` exactly and changes TuRPBO's options:
    ``--reuse`` copies the Sobol runs (never executed) and computes the TuRPBO ones."""
    import localpbo_core.sweep as sweep_module

    text = Path(spec.path).read_text().replace("name: tiny", "name: tiny_other")
    text = text.replace("num_restarts: 2", "num_restarts: 3")
    path = tmp_path / "tiny_other.yaml"
    path.write_text(text)
    other = load_spec(str(path))
    out = tmp_path / "other"
    cmd = ["sweep", str(path), "--out", str(out), "--reuse", str(reference), "--dry-run"]
    assert main(cmd) == 0
    listing = capsys.readouterr().out
    assert "hartmann6__sobol__seed0" in listing and "2 reuse, 2 will run" in listing

    executed: list[str] = []
    real = sweep_module.execute_run

    def spy(plan, *checkpointing):
        executed.append(plan.run_id)
        return real(plan, *checkpointing)

    monkeypatch.setattr(sweep_module, "execute_run", spy)
    result = sweep(other, out, in_process=True, progress=False, reuse=[tmp_path, reference])
    assert sorted(result.reused) == ["hartmann6__sobol__seed0", "hartmann6__sobol__seed1"]
    assert sorted(executed) == sorted(result.finished)
    assert sorted(result.finished) == ["hartmann6__turpbo__seed0", "hartmann6__turpbo__seed1"]
    for plan in other.runs():
        doc = read_run(run_path(out, plan))
        assert doc["run"]["spec"] == "tiny_other"
        if plan.run_id in result.reused:
            source = read_run(run_path(reference, plan))
            assert doc["run"]["reused_from"] == f"tiny/{plan.run_id}"
            assert {k: v for k, v in doc.items() if k != "run"} == {
                k: v for k, v in source.items() if k != "run"
            }
        else:
            assert "reused_from" not in doc["run"]
    report = write_report([out], tmp_path / "report").read_text()
    assert "| tiny_other | hartmann6 | sobol | 2 |" in report
    assert "(2 runs copied from tiny) |" in report
    turpbo_row = next(
        line for line in report.splitlines() if "| tiny_other | hartmann6 | turpbo" in line
    )
    assert "copied" not in turpbo_row
    again = sweep(other, out, in_process=True, progress=False, reuse=[reference])
    assert not again.reused and not again.finished and len(again.skipped) == 4
    capsys.readouterr()
    with pytest.raises(SystemExit) as exc:
        main(["sweep", str(path), "--out", str(out), "--reuse", str(tmp_path / "none")])
    assert exc.value.code == 2 and "--reuse: " in capsys.readouterr().err


def test_a_copy_of_a_rerun_replaced_nothing(spec, reference, tmp_path) -> None:
    """A copy (``--reuse``) of a re-run does not carry the re-run's ``replaced`` block: the
    copy replaced no run of its own sweep."""
    from localpbo_core.sweep import reused_document, write_run

    plan = spec.runs()[0]
    source = tmp_path / "runs" / f"{plan.run_id}.json.gz"
    doc = read_run(run_path(reference, plan))
    write_run(source, {**doc, "replaced": {"identical": 0}})
    copy = reused_document(source, plan)
    assert "replaced" not in copy
    assert {k: v for k, v in copy.items() if k != "run"} == {
        k: v for k, v in doc.items() if k != "run"
    }


def test_reuse_matches_runs_by_settings_with_options_at_their_defaults(
    spec, reference, tmp_path, monkeypatch
) -> None:
    """Another spec spells out defaults under new labels (``sobol_q1``: ``batch_size: 1``;
    ``turpbo_ts``: ``acquisition: ts``) and changes one option off its default
    (``turpbo_r3``): the first two reuse ``tiny``'s runs under other run ids, the third is
    computed. The copies carry the new spec's settings, so the next sweep finds them
    finished."""
    import localpbo_core.sweep as sweep_module

    turpbo = "num_raw_samples: 64, num_restarts: 2, num_features: 256"
    text = f"""schema: localpbo/experiment/v1
name: tiny_defaults
paper: none (test)
seeds: 0-1
settings: {{initial_design: 2, budget: 8, noise_fraction: 0.1}}
problems:
  - problem: hartmann6
algorithms:
  - {{algorithm: sobol, label: sobol_q1, options: {{batch_size: 1}}}}
  - {{algorithm: turpbo, label: turpbo_ts, options: {{{turpbo}, acquisition: ts}}}}
  - {{algorithm: turpbo, label: turpbo_r3, options: {{{turpbo.replace("2,", "3,")}}}}}
"""
    path = tmp_path / "tiny_defaults.yaml"
    path.write_text(text)
    other = load_spec(str(path))
    out = tmp_path / "defaults"
    assert "4 reuse, 2 will run" in format_dry_run(out, other.runs(), None, [reference])

    executed: list[str] = []
    real = sweep_module.execute_run
    monkeypatch.setattr(
        sweep_module,
        "execute_run",
        lambda plan, *checkpointing: executed.append(plan.run_id) or real(plan, *checkpointing),
    )
    result = sweep(other, out, in_process=True, progress=False, reuse=[reference])
    assert sorted(executed) == sorted(result.finished)
    assert sorted(result.finished) == ["hartmann6__turpbo_r3__seed0", "hartmann6__turpbo_r3__seed1"]
    assert len(result.reused) == 4
    for plan in other.runs():
        doc = read_run(run_path(out, plan))
        assert doc["settings"] == settings_document(plan.settings)
        if plan.run_id not in result.reused:
            continue
        source_id = plan.run_id.replace("_q1", "").replace("_ts", "")
        source = read_run(reference / "runs" / f"{source_id}.json.gz")
        assert doc["run"]["reused_from"] == f"tiny/{source_id}"
        assert source["settings"] != doc["settings"]
        assert {k: v for k, v in doc.items() if k not in ("run", "settings")} == {
            k: v for k, v in source.items() if k not in ("run", "settings")
        }
    again = sweep(other, out, in_process=True, progress=False, reuse=[reference])
    assert not again.reused and not again.finished and len(again.skipped) == 6


def test_effective_settings_fill_in_defaults_and_keep_explicit_values() -> None:
    base = {"algorithm": "qeubo", "problem": "levy32", "seed": 3, "initial_design": 2}
    plain = effective_settings({**base, "optimizer_options": {}})
    spelled = effective_settings({**base, "optimizer_options": {"batch_size": 1}})
    other = effective_settings({**base, "optimizer_options": {"batch_size": 2}})
    assert plain is not None and plain == spelled != other
    assert plain["optimizer_options"]["num_raw_samples"] == 1024
    assert "initial_design" not in plain["optimizer_options"]  # a settings field
    assert effective_settings({**base, "algorithm": "nope", "optimizer_options": {}}) is None
