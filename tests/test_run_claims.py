"""Run claims: two sweeps on one folder never compute the same run, and a claim dies with
its process (SIGKILL included)."""

from __future__ import annotations

import json
import os
import re
import signal
import socket
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest

from localpbo_core.cli import main
from localpbo_core.run_claims import claim_path, holder, try_claim
from localpbo_core.settings import SettingError
from localpbo_core.sweep import (
    RunTimes,
    check_writable,
    format_dry_run,
    parse_duration,
    read_run,
    run_path,
    sweep,
    write_run,
)


def test_a_claim_is_exclusive_until_released(tmp_path) -> None:
    first = try_claim(tmp_path, "r1")
    assert first is not None and first.held
    assert try_claim(tmp_path, "r1") is None  # another open file: refused, also in-process
    assert try_claim(tmp_path, "r2") is not None  # other runs are free
    who = holder(tmp_path, "r1")
    assert who is not None and who.pid == os.getpid() and who.host == socket.gethostname()
    assert f"pid {os.getpid()} on host {socket.gethostname()} since " in who.describe()
    first.release()
    assert not first.held and not claim_path(tmp_path, "r1").exists()
    assert holder(tmp_path, "r1") is None
    again = try_claim(tmp_path, "r1")
    assert again is not None
    again.release()
    again.release()  # twice is harmless


def test_a_left_claim_file_holds_nothing_and_unreadable_holders_are_anonymous(tmp_path) -> None:
    path = claim_path(tmp_path, "r1")
    path.parent.mkdir(parents=True)
    path.write_text(json.dumps({"pid": 1, "host": "elsewhere"}))  # a sweep that ended
    assert holder(tmp_path, "r1") is None
    with try_claim(tmp_path, "r1") as taken:
        assert taken is not None
        assert json.loads(path.read_text())["pid"] == os.getpid()
        for hostile in (b"", b"[1, 2]", b'{"pid": true, "host": 3}', b"\xff\xfe{"):
            with open(path, "r+b") as fh:
                fh.truncate(0)
                fh.write(hostile)
            assert holder(tmp_path, "r1").describe() == "another sweep"
    assert not path.exists()


_HOLD = textwrap.dedent(
    """
    import sys, time
    from pathlib import Path
    from localpbo_core.run_claims import try_claim
    claim = try_claim(Path(sys.argv[1]), sys.argv[2])
    print("held" if claim else "refused", flush=True)
    time.sleep(600)
    """
)


def test_a_claim_dies_with_its_process_even_by_sigkill(tmp_path) -> None:
    proc = subprocess.Popen(
        [sys.executable, "-c", _HOLD, str(tmp_path), "r1"], stdout=subprocess.PIPE, text=True
    )
    try:
        assert proc.stdout.readline().strip() == "held"
        assert try_claim(tmp_path, "r1") is None
        assert holder(tmp_path, "r1").pid == proc.pid
    finally:
        proc.send_signal(signal.SIGKILL)
        proc.wait()
    assert claim_path(tmp_path, "r1").exists()  # the file stays, the lock went with it
    assert holder(tmp_path, "r1") is None
    taken = try_claim(tmp_path, "r1")
    assert taken is not None
    taken.release()


def _trace(doc: dict) -> dict:
    keep = ("settings", "candidates", "answers")
    records = [{k: v for k, v in r.items() if k != "decision_seconds"} for r in doc["records"]]
    return {**{k: doc[k] for k in keep}, "records": records}


def test_a_sweep_passes_over_runs_another_sweep_holds(tiny_spec, tiny_reference, tmp_path) -> None:
    plans = tiny_spec.runs()
    held = try_claim(tmp_path, plans[0].run_id)  # as another sweep would, mid-run
    assert "under way" in format_dry_run(tmp_path, plans, None).splitlines()[1]
    result = sweep(tiny_spec, tmp_path, in_process=True, progress=False)
    assert list(result.elsewhere) == [plans[0].run_id]
    assert f"pid {os.getpid()}" in result.elsewhere[plans[0].run_id]
    assert sorted(result.finished) == sorted(p.run_id for p in plans[1:])
    assert not run_path(tmp_path, plans[0]).exists()
    left = [p.name for p in (tmp_path / ".claims").iterdir()]
    assert left == [f"{plans[0].run_id}.claim"]  # only the held claim is left
    held.release()
    again = sweep(tiny_spec, tmp_path, in_process=True, progress=False)
    assert again.finished == [plans[0].run_id] and not again.elsewhere
    for plan in plans:
        assert _trace(read_run(run_path(tmp_path, plan))) == _trace(
            read_run(run_path(tiny_reference, plan))
        )
    assert not list((tmp_path / ".claims").iterdir())


def test_max_runs_counts_the_runs_this_sweep_computes(tiny_spec, tmp_path) -> None:
    plans = tiny_spec.runs()
    held = try_claim(tmp_path, plans[0].run_id)
    result = sweep(tiny_spec, tmp_path, in_process=True, progress=False, max_runs=2)
    held.release()
    assert result.finished == [plans[1].run_id, plans[2].run_id]
    assert result.pending == [plans[3].run_id] and list(result.elsewhere) == [plans[0].run_id]


def test_a_run_stored_meanwhile_by_another_sweep_is_skipped(
    tiny_spec, tiny_reference, tmp_path
) -> None:
    plans = tiny_spec.runs()
    copied = []

    def store_the_next_as_another_sweep(plan) -> None:
        following = plans[plans.index(plan) + 1 :]
        if following and not copied:  # after planning, before this sweep reaches it
            target = run_path(tmp_path, following[0])
            target.write_bytes(run_path(tiny_reference, following[0]).read_bytes())
            copied.append(following[0].run_id)

    result = sweep(
        tiny_spec,
        tmp_path,
        in_process=True,
        progress=False,
        on_stored=store_the_next_as_another_sweep,
    )
    assert result.skipped == copied and len(result.finished) == 3 and not result.elsewhere


def _cli_sweep(out: Path) -> subprocess.Popen[str]:
    cmd = [sys.executable, "-m", "localpbo_core.cli", "sweep", "tiny", "--out", str(out)]
    return subprocess.Popen(
        [*cmd, "--in-process", "--no-progress"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )


def _finished(out: str) -> int:
    """The count of runs a sweep's summary line says it finished."""
    found = re.search(r"(\d+) runs? finished", out)
    assert found, out
    return int(found.group(1))


@pytest.mark.timeout(900)  # both cores may be loaded by other processes
def test_the_same_command_in_two_processes_splits_the_runs(
    tiny_spec, tiny_reference, tmp_path
) -> None:
    """Two ``localpbo sweep --in-process`` processes started together on one folder: every
    run is computed by exactly one of them, and the runs equal a single sweep's."""
    procs = [_cli_sweep(tmp_path), _cli_sweep(tmp_path)]
    outputs = [p.communicate(timeout=800) for p in procs]
    assert [p.returncode for p in procs] == [0, 0], outputs
    finished = [_finished(out) for out, _ in outputs]
    assert sum(finished) == 4, outputs  # no run computed twice, none left
    for plan in tiny_spec.runs():
        assert _trace(read_run(run_path(tmp_path, plan))) == _trace(
            read_run(run_path(tiny_reference, plan))
        )
    assert not list((tmp_path / ".claims").iterdir())


@pytest.mark.timeout(900)
def test_a_sweep_killed_mid_run_leaves_its_run_to_the_next(
    tiny_spec, tiny_reference, tmp_path
) -> None:
    """SIGKILL of a sweep while it computes: its claim goes with it; the next sweep runs what
    is missing, and the stored runs equal a single sweep's."""
    proc = _cli_sweep(tmp_path)
    claims = tmp_path / ".claims"
    deadline = time.monotonic() + 300
    while not (claims.is_dir() and any(claims.iterdir())):
        assert proc.poll() is None and time.monotonic() < deadline
        time.sleep(0.01)
    proc.send_signal(signal.SIGKILL)
    proc.communicate()
    assert main(["sweep", "tiny", "--out", str(tmp_path), "--in-process", "--no-progress"]) == 0
    for plan in tiny_spec.runs():
        assert _trace(read_run(run_path(tmp_path, plan))) == _trace(
            read_run(run_path(tiny_reference, plan))
        )
    assert not list(claims.iterdir())


def test_an_unwritable_out_is_refused_before_any_run(tmp_path) -> None:
    blocker = tmp_path / "a-file"
    blocker.write_text("")
    with pytest.raises(SettingError) as refused:
        check_writable(blocker / "sub")
    assert refused.value.field == "--out" and "Not a directory" in refused.value.reason
    cmd = [sys.executable, "-m", "localpbo_core.cli", "sweep", "tiny", "--out", str(blocker)]
    done = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
    assert done.returncode == 2 and "--out: cannot write runs to" in done.stderr, done.stderr
    assert "Traceback" not in done.stderr


def test_durations_parse_and_bad_ones_are_refused() -> None:
    assert parse_duration("5400") == 5400.0
    assert parse_duration("90m") == 5400.0
    assert parse_duration("1h30m") == 5400.0
    assert parse_duration("1d2h3m4s") == 86400 + 7200 + 180 + 4
    assert parse_duration(" 2.5h ") == 9000.0
    for bad in ("", "0", "0m", "-5m", "1x", "h", "1h 30m", "inf", "nan"):
        with pytest.raises(SettingError) as refused:
            parse_duration(bad)
        assert refused.value.field == "--time-limit"


def _stored_with_seconds(source: Path, target: Path, seconds: float, reused: bool = False) -> None:
    doc = read_run(source)
    doc["run_seconds"] = seconds
    if reused:
        doc["run"] = {**doc["run"], "reused_from": "elsewhere/x"}
    write_run(target, doc)


def test_run_times_are_the_groups_measured_runs(tiny_spec, tiny_reference, tmp_path) -> None:
    plans = tiny_spec.runs()  # sobol seeds 0-1, turpbo seeds 0-1 on hartmann6
    sobol0, sobol1, turpbo0, turpbo1 = plans
    _stored_with_seconds(run_path(tiny_reference, turpbo0), run_path(tmp_path, turpbo0), 30.0)
    _stored_with_seconds(run_path(tiny_reference, sobol0), run_path(tmp_path, sobol0), 9e9, True)
    times = RunTimes(tmp_path)
    assert RunTimes.group("hartmann6__turpbo__noise0.1__seed12") == "hartmann6__turpbo__noise0.1"
    assert times.longest(turpbo1) == 30.0
    assert times.longest(sobol1) is None  # a copy made by --reuse measures nothing
    times.add(turpbo1, {"run_seconds": 45.0, "run": {}})
    assert times.longest(turpbo0) == 45.0


def test_a_run_that_would_end_after_the_limit_is_not_started(
    tiny_spec, tiny_reference, tmp_path
) -> None:
    plans = tiny_spec.runs()
    _stored_with_seconds(run_path(tiny_reference, plans[2]), run_path(tmp_path, plans[2]), 7200.0)
    result = sweep(
        tiny_spec, tmp_path, in_process=True, progress=False, time_limit=3600.0,
        checkpoint_every=None,
    )  # fmt: skip
    assert result.over_time == [plans[3].run_id] == result.pending
    assert sorted(result.finished) == sorted(p.run_id for p in plans[:2])
    assert not result.interrupted and not result.time_limit_reached
    assert not run_path(tmp_path, plans[3]).exists()
    assert not list((tmp_path / ".claims").iterdir())
    # with checkpoints (the default) it starts when one interval is left: its progress is kept
    held = sweep(tiny_spec, tmp_path, in_process=True, progress=False, time_limit=500.0)
    assert held.over_time == [plans[3].run_id]
    started = sweep(tiny_spec, tmp_path, in_process=True, progress=False, time_limit=3600.0)
    assert started.finished == [plans[3].run_id] and started.over_time == []


def test_a_group_with_no_run_here_takes_the_times_of_another_folder(
    tiny_spec, tiny_reference, tmp_path
) -> None:
    """``--times-from``: the other folder's longest run of the same group stands in until the
    sweep's own folder has one; a group measured nowhere still starts."""
    sobol0, sobol1, turpbo0, turpbo1 = tiny_spec.runs()
    here, elsewhere, third = tmp_path / "here", tmp_path / "elsewhere", tmp_path / "third"
    _stored_with_seconds(run_path(tiny_reference, turpbo0), run_path(elsewhere, turpbo0), 50.0)
    _stored_with_seconds(run_path(tiny_reference, turpbo1), run_path(third, turpbo1), 70.0)
    _stored_with_seconds(run_path(tiny_reference, sobol0), run_path(third, sobol0), 5.0, True)
    times = RunTimes(here, [elsewhere, third])
    assert times.longest(turpbo0) == 70.0  # the longest over every other folder
    assert times.longest(sobol1) is None  # a copy made by --reuse measures nothing
    assert RunTimes(here).longest(turpbo0) is None
    times.add(turpbo0, {"run_seconds": 20.0, "run": {}})
    assert times.longest(turpbo1) == 20.0  # its own run replaces the stand-in
    _stored_with_seconds(run_path(tiny_reference, turpbo1), run_path(here, turpbo1), 10.0)
    assert RunTimes(here, [elsewhere, third]).longest(turpbo0) == 10.0

    result = sweep(
        tiny_spec, here, in_process=True, progress=False, time_limit=60.0, times_from=[third]
    )
    assert result.over_time == [] and sorted(result.finished) == sorted(
        p.run_id for p in (sobol0, sobol1, turpbo0)
    )
    fresh = tmp_path / "fresh"
    result = sweep(
        tiny_spec, fresh, in_process=True, progress=False, time_limit=60.0, times_from=[third]
    )
    assert result.over_time == [turpbo0.run_id, turpbo1.run_id] == result.pending
    assert sorted(result.finished) == sorted(p.run_id for p in (sobol0, sobol1))
    assert not list((fresh / ".claims").iterdir())


def test_times_from_is_refused_without_a_limit_or_a_folder(tmp_path) -> None:
    cmd = [sys.executable, "-m", "localpbo_core.cli", "sweep", "tiny", "--out", str(tmp_path)]
    cmd += ["--in-process", "--no-progress", "--times-from"]
    done = subprocess.run([*cmd, str(tmp_path)], capture_output=True, text=True, timeout=120)
    assert done.returncode == 2 and "--times-from: only --time-limit reads it" in done.stderr
    missing = str(tmp_path / "missing")
    done = subprocess.run(
        [*cmd, missing, "--time-limit", "1h"], capture_output=True, text=True, timeout=120
    )
    assert done.returncode == 2 and f"--times-from: {missing} is not a folder" in done.stderr
    assert "Traceback" not in done.stderr and not (tmp_path / "runs").exists()


@pytest.mark.timeout(900)
def test_the_time_limit_stops_the_runs_under_way(tmp_path) -> None:
    """A limit shorter than one run: the sweep stops it as on SIGTERM (exit 130), stores
    nothing, leaves no claim, and says why; the same command without the limit continues."""
    cmd = [sys.executable, "-m", "localpbo_core.cli", "sweep", "synthetic", "--out", str(tmp_path)]
    cmd += ["--problems", "levy32", "--algorithms", "turpbo", "--seeds", "0"]  # minutes long
    cmd += ["--in-process", "--no-progress"]
    began = time.monotonic()
    done = subprocess.run([*cmd, "--time-limit", "2s"], capture_output=True, text=True, timeout=600)
    assert done.returncode == 130, done
    assert "--time-limit 2s reached: the runs under way were stopped" in done.stdout
    assert "1 left" in done.stdout and time.monotonic() - began < 60
    assert not list((tmp_path / "runs").glob("*.json.gz"))
    assert not list((tmp_path / ".claims").iterdir())


@pytest.mark.timeout(1200)
def test_three_sweeps_killed_at_random_points_still_store_every_run_once(
    tiny_spec, tiny_reference, tmp_path
) -> None:
    """Three ``--in-process`` sweeps of one folder, each SIGKILLed at a random moment (seeded)
    and started again, until the folder is complete: every stored run equals the
    uninterrupted sweep's, no temporary file or claim is left, and a final sweep finds
    everything stored."""
    import random

    rng = random.Random(7)
    runs = tmp_path / "runs"
    deadline = time.monotonic() + 900
    rounds = 0
    while len(list(runs.glob("*.json.gz"))) < 4:
        assert time.monotonic() < deadline, "the sweeps made no progress"
        procs = [_cli_sweep(tmp_path) for _ in range(3)]
        time.sleep(rng.uniform(2.0, 8.0))  # imports take ~2 s; a run of the tiny spec ~1-5 s
        for proc in procs:
            if rng.random() < 0.7:
                proc.send_signal(signal.SIGKILL)
        for proc in procs:
            proc.communicate(timeout=600)
        rounds += 1
    for plan in tiny_spec.runs():
        assert _trace(read_run(run_path(tmp_path, plan))) == _trace(
            read_run(run_path(tiny_reference, plan))
        )
    assert not [p.name for p in runs.iterdir() if not p.name.endswith(".json.gz")]
    cmd = [sys.executable, "-m", "localpbo_core.cli", "sweep", "tiny", "--out", str(tmp_path)]
    final = subprocess.run(
        [*cmd, "--in-process", "--no-progress"],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert final.returncode == 0 and "0 runs finished, 4 already stored" in final.stdout
    assert not list((tmp_path / ".claims").iterdir())
    assert rounds >= 1


def test_the_claims_holder_removes_a_killed_writers_temporary_file(tiny_spec, tmp_path) -> None:
    plan = tiny_spec.runs()[0]
    final = run_path(tmp_path, plan)
    final.parent.mkdir(parents=True)
    partial = final.with_name(f".{final.name}.99999999.tmp")
    partial.write_bytes(b"\x1f\x8b half a run")
    other = final.with_name(f".{tiny_spec.runs()[1].run_id}.json.gz.99999999.tmp")
    other.write_bytes(b"")
    held = try_claim(tmp_path, tiny_spec.runs()[1].run_id)  # its writer may still be alive
    sweep(tiny_spec, tmp_path, runs=[plan], in_process=True, progress=False)
    assert final.exists() and not partial.exists() and other.exists()
    held.release()


def test_a_copy_by_reuse_waits_for_the_claim_too(tiny_spec, tiny_reference, tmp_path) -> None:
    plans = tiny_spec.runs()
    held = try_claim(tmp_path, plans[0].run_id)
    result = sweep(tiny_spec, tmp_path, in_process=True, progress=False, reuse=[tiny_reference])
    held.release()
    assert list(result.elsewhere) == [plans[0].run_id]
    assert sorted(result.reused) == sorted(p.run_id for p in plans[1:]) and not result.finished
    assert not run_path(tmp_path, plans[0]).exists()
