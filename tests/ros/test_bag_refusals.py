"""Bags that are not what they claim: an edited run config, messages of another run, a file
that is not MCAP, a file cut short. ``replay --verify``, ``run --resume``, ``replay`` and
``bag-info`` refuse or report each, naming the file and the field (or the foreign run)."""

from __future__ import annotations

import os
import subprocess
import sys
from dataclasses import replace
from pathlib import Path
from typing import Any

import pytest
from localpbo_ros.bagtools import NotABagError, load_run
from localpbo_ros.commands import main as cli_main
from localpbo_ros.replay import resumable, verify

from localpbo_core.provenance import recording_platform
from localpbo_msgs_py import CandidateMsg, RunConfig
from localpbo_msgs_py.bag import PLATFORM_METADATA, BagWriter, read_messages, summarize
from localpbo_msgs_py.topics import ALL_TOPICS, CANDIDATE, RUN_CONFIG, STATUS

BAG = Path(__file__).resolve().parents[2] / "bags" / "swimmer_sobol_s0.mcap"


def rewrite(src: Path, dst: Path, drop: tuple[str, ...] = (), **edit: Any) -> Path:
    """``src`` copied message by message into ``dst`` with its run config's fields edited
    (what a user editing a bag's config, or pairing one run's config with another run's
    messages, would produce); the file itself is a whole, valid bag."""
    with BagWriter(dst) as writer:
        writer.add_suite_topics(ALL_TOPICS)
        for rec in read_messages(src):
            if rec.topic in drop:
                continue
            msg = rec.message
            if rec.topic == RUN_CONFIG.name:
                config = RunConfig.decode(msg)
                assert isinstance(config, RunConfig)
                msg = replace(config, **edit).encode()
            writer.copy(rec, msg)
    return dst


def resume(bag: Path, out: Path, capsys: Any) -> tuple[int, str]:
    code = cli_main(["run", "--resume", str(bag), "--out", str(out), "--no-progress"])
    return code, capsys.readouterr().err


def verify_cli(bag: Path, capsys: Any) -> tuple[int, str]:
    code = cli_main(["replay", "--verify", str(bag)])
    captured = capsys.readouterr()
    return code, captured.out + captured.err


EDITS = {
    "seed": ({"seed": 1}, "fields seed, algorithm"),
    "budget lowered": ({"budget": 30}, "field budget: candidate 30 is recorded"),
    "budget raised": ({"budget": 60}, "field budget: the recorded run finished after 40"),
    "task": (
        {"task": "hartmann6", "dim": 6, "lower": (0.0,) * 6, "upper": (1.0,) * 6},
        "field task: 40 recorded candidate(s) do not fit the run config's task 'hartmann6'",
    ),
}


@pytest.mark.parametrize("edit", sorted(EDITS))
def test_an_edited_run_config_is_refused(edit: str, tmp_path: Path, capsys: Any) -> None:
    fields, says = EDITS[edit]
    bag = rewrite(BAG, tmp_path / "edited.mcap", **fields)
    code, text = verify_cli(bag, capsys)
    assert code == 1 and text.startswith("MISMATCH: ") and says in text, text
    out = tmp_path / "out"
    code, err = resume(bag, out, capsys)
    assert code == 2, err
    assert err.startswith(f"localpbo run: --resume: {bag}: "), err
    assert says in err, err
    assert not out.exists()  # refused before any bag is written


def moved(src: Path, dst: Path, platform: dict[str, str] | None) -> Path:
    """``src`` with candidate 5's θ[0] off by 1e-12 (what another CPU's kernels make of a
    model-based run) and, unless None, ``platform`` as its ``localpbo/platform`` record."""
    with BagWriter(dst) as writer:
        if platform is not None:
            writer.add_metadata(PLATFORM_METADATA, platform)
        writer.add_suite_topics(ALL_TOPICS)
        for rec in read_messages(src):
            msg = rec.message
            if rec.topic == CANDIDATE.name:
                cand = CandidateMsg.decode(msg)
                assert isinstance(cand, CandidateMsg)
                if cand.candidate_id == 5:
                    theta = (cand.theta[0] + 1e-12, *cand.theta[1:])
                    msg = replace(cand, theta=theta).encode()
            writer.copy(rec, msg)
    return dst


@pytest.mark.parametrize("where", ["elsewhere", "here", "unknown"])
def test_a_bag_from_another_platform_says_so(where: str, tmp_path: Path, capsys: Any) -> None:
    """A rebuilt candidate that parts from the recorded one is put down to the platform when
    the bag's ``localpbo/platform`` record differs from here (naming what differs), to an
    edited run config when it is the same, and to either when the bag does not say."""
    here = recording_platform()
    other = {**here, "cpu_flags": "sse4_2 avx fma avx2 avx512f", "libraries.torch": "0.0"}
    platform = {"elsewhere": other, "here": here, "unknown": None}[where]
    bag = moved(BAG, tmp_path / f"{where}.mcap", platform)
    report = verify(bag)
    assert not report.ok and report.mismatch.startswith("candidate 5: θ[0] recorded ")
    assert "a gap of 1e-12" in report.mismatch
    platform_said = "the bag was recorded on another platform or by other code"
    config_said = "fields seed, algorithm, algorithm_options, initial_design"
    if where == "elsewhere":
        assert platform_said in report.mismatch and config_said not in report.mismatch
        assert f"cpu_flags: {other['cpu_flags']} -> {here['cpu_flags']}" in report.mismatch
        assert f"libraries.torch: 0.0 -> {here['libraries.torch']}" in report.mismatch
    elif where == "here":
        assert config_said in report.mismatch and "platform" not in report.mismatch
    else:
        assert config_said in report.mismatch
        assert "the bag has no localpbo/platform record" in report.mismatch
    code, err = resume(bag, tmp_path / "out", capsys)
    assert code == 2 and "candidate 5: θ[0]" in err, err
    assert (platform_said in err) == (where == "elsewhere"), err
    assert summarize(bag).platform == (platform or {})


def test_the_unedited_copy_passes(tmp_path: Path) -> None:
    """The rewrite itself changes nothing the checks see (so the refusals above are the
    edits')."""
    bag = rewrite(BAG, tmp_path / "copy.mcap")
    assert verify(bag).ok and resumable(bag).config == load_run(BAG).config


def test_messages_of_another_run_are_refused_naming_it(tmp_path: Path, capsys: Any) -> None:
    bag = rewrite(BAG, tmp_path / "foreign.mcap", run_id="mine")  # every message: another run
    report = verify(bag)
    assert not report.ok and "'swimmer-sobol-s0' (" in report.mismatch, report.format()
    assert "beside 0 of run 'mine'" in report.mismatch
    code, text = verify_cli(bag, capsys)
    assert code == 1 and "holds messages of another run: 'swimmer-sobol-s0'" in text
    code, err = resume(bag, tmp_path / "out", capsys)
    assert code == 2 and "holds messages of another run: 'swimmer-sobol-s0'" in err, err
    code = cli_main(["bag-info", str(bag)])
    assert code == 0
    assert "not one run's record: holds messages of another run" in capsys.readouterr().out


def test_a_file_that_is_not_a_bag(tmp_path: Path, capsys: Any) -> None:
    junk = tmp_path / "random.mcap"
    junk.write_bytes(os.urandom(5000))
    with pytest.raises(NotABagError):
        load_run(junk)
    for argv in (["replay", str(junk)], ["replay", "--verify", str(junk)], ["bag-info", str(junk)]):
        assert cli_main(argv) == 2, argv
        err = capsys.readouterr().err
        assert f"{junk}: not an MCAP bag" in err, (argv, err)
    code, err = resume(junk, tmp_path / "out", capsys)
    assert code == 2 and f"{junk}: not an MCAP bag" in err


def test_replay_of_a_non_bag_exits_2_from_the_shell(tmp_path: Path) -> None:
    junk = tmp_path / "random.bin"
    junk.write_bytes(os.urandom(4096))
    env = {**os.environ, "ROS_AUTOMATIC_DISCOVERY_RANGE": "OFF"}
    done = subprocess.run(
        [sys.executable, "-m", "localpbo_ros.commands", "replay", str(junk)],
        env=env,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == 2 and "not an MCAP bag" in done.stderr, done
    assert "published" not in done.stdout


def cut(tmp_path: Path, size: int = 30_000) -> Path:
    """The committed bag cut inside a record (a copy stopped short)."""
    data = BAG.read_bytes()
    short = tmp_path / "cut.mcap"
    short.write_bytes(data[:size])
    info = summarize(short)
    assert info.whole_bytes is not None and info.whole_bytes < size  # really mid-record
    return short


def test_a_truncated_bag_says_so(tmp_path: Path, capsys: Any) -> None:
    short = cut(tmp_path)
    assert cli_main(["bag-info", str(short)]) == 0
    out = capsys.readouterr().out
    assert "file complete: no: the file ends early, cut inside a record at byte " in out, out
    assert "run finished: no: stopped at 16 of 40 evaluations (optimizer running)" in out
    code, text = verify_cli(short, capsys)
    assert code == 0 and text.startswith("OK: 16 candidates"), text
    assert "note: the file ends early: cut inside a record at byte 29991 of 30000" in text
    assert "checked what was read" in text


def test_resume_of_a_truncated_bag_says_what_it_read(tmp_path: Path) -> None:
    short = cut(tmp_path)
    resumed = tmp_path / "resumed.mcap"
    env = {**os.environ, "ROS_AUTOMATIC_DISCOVERY_RANGE": "OFF"}
    cmd = [sys.executable, "-m", "localpbo_ros.commands", "run", "--resume", str(short)]
    done = subprocess.run(
        [*cmd, "--bag", str(resumed), "--no-progress"],
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert done.returncode == 0, done.stderr[-3000:]
    assert (
        f"localpbo run: --resume: {short}: the file ends early: cut inside a record at byte "
        "29991 of 30000 (79 messages readable before it); continuing from what was read"
    ) in done.stderr
    report = verify(resumed)
    assert report.ok and report.candidates_checked == 40, report.format()
    assert load_run(resumed).finished == "yes (40 of 40 evaluations)"


def test_run_finished_is_unknown_without_the_optimizer_status(tmp_path: Path, capsys: Any) -> None:
    bag = rewrite(BAG, tmp_path / "no_status.mcap", drop=(STATUS.name,))
    assert cli_main(["bag-info", str(bag)]) == 0
    out = capsys.readouterr().out
    assert "file complete: yes (closed cleanly)" in out
    assert "run finished: unknown: no optimizer status recorded (40 of 40 evaluations)" in out
