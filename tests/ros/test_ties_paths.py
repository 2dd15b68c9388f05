"""The run protocol's contract with "can't tell" answers: a run whose oracle answers
``indifferent`` gives bit-identical candidates, returns and outcomes (kind and winner) in
``localpbo bench`` and ``localpbo run``; its bag names the tie settings, verifies offline and
resumes (a bag cut mid-run continues to the same outcomes)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest
from localpbo_ros.bagtools import load_run, outcome_counts
from localpbo_ros.commands import main as cli_main
from localpbo_ros.commands import run_settings
from localpbo_ros.driver import settings_of
from localpbo_ros.replay import verify
from localpbo_ros.suite import run_suite

from localpbo_msgs_py import DuelOutcome
from localpbo_msgs_py.bag import BagWriter, read_messages
from localpbo_msgs_py.topics import ALL_TOPICS, DUEL_OUTCOME

from .same_run import (
    ALGORITHM,
    BUDGET,
    NOISE,
    OPTIONS,
    SEED,
    TASK,
    TASK_OPTIONS,
    answers_of,
    from_bag,
    from_bench,
)

TIE_THRESHOLD = 0.5
INDIFFERENCE = 0.15


def node_parameters() -> dict[str, Any]:
    """What ``localpbo run`` passes the optimizer node for the same run."""
    args = [
        "--algorithm",
        ALGORITHM,
        "--algorithm-options",
        json.dumps(OPTIONS),
        "--task",
        TASK,
        "--task-options",
        json.dumps(TASK_OPTIONS),
        "--seed",
        str(SEED),
        "--budget",
        str(BUDGET),
        "--noise",
        str(NOISE),
        "--tie-threshold",
        str(TIE_THRESHOLD),
        "--indifference",
        str(INDIFFERENCE),
        "--run-id",
        "ties",
    ]
    import argparse

    from localpbo_ros.commands import add_subcommands

    parser = argparse.ArgumentParser()
    add_subcommands(parser.add_subparsers())
    return run_settings(parser.parse_args(["run", *args]))


def cut_before(bag: Path, out: Path, duel_id: int) -> None:
    """A copy of ``bag`` up to the first outcome of duel ``duel_id`` (a run stopped there)."""
    with BagWriter(out) as writer:
        writer.add_suite_topics(ALL_TOPICS)
        for rec in read_messages(bag):
            if rec.topic == DUEL_OUTCOME.name:
                msg = DuelOutcome.decode(rec.message)
                if isinstance(msg, DuelOutcome) and msg.duel_id >= duel_id:
                    break
            writer.copy(rec)


@pytest.mark.slow
def test_bench_and_run_agree_on_cant_tell_answers_and_the_bag_resumes(tmp_path: Path) -> None:
    reference = from_bench(tmp_path, TIE_THRESHOLD, INDIFFERENCE)
    assert len(reference["native"]) == BUDGET
    kinds = [a[2] for a in reference["answers"].values()]
    assert "indifferent" in kinds and "decisive" in kinds

    bag = tmp_path / "one.mcap"
    summary = run_suite(node_parameters(), bag, timeout_s=300)
    assert summary.state == "done", summary.error
    got = from_bag(bag)
    # floats compared exactly: bit-identical, not approximately equal
    assert got["native"] == reference["native"]
    assert got["values"] == reference["values"]
    assert got["answers"] == reference["answers"]

    # the bag explains itself: the tie settings are in the run config's oracle section
    config = load_run(bag).config
    assert config.options["oracle"] == {
        "noise_fraction": NOISE,
        "tie_threshold": TIE_THRESHOLD,
        "indifference": INDIFFERENCE,
    }
    settings = settings_of(config)
    assert (settings.tie_threshold, settings.indifference) == (TIE_THRESHOLD, INDIFFERENCE)
    report = verify(bag)
    assert report.ok and report.candidates_checked == BUDGET, report.format()
    assert report.outcomes_used == len(reference["answers"])
    assert cli_main(["replay", "--verify", str(bag)]) == 0
    counts = outcome_counts(load_run(bag))
    assert (counts.decisive, counts.indifferent, counts.failed) == (
        kinds.count("decisive"),
        kinds.count("indifferent"),
        0,
    )
    assert counts.format() == (
        f"outcomes: {len(kinds)} duels, {counts.decisive} decisive, "
        f"{counts.indifferent} can't tell, 0 failed"
    )

    # stopped after the first tie and one more duel: --resume continues to the same run
    first_tie = min(d for d, a in reference["answers"].items() if a[2] == "indifferent")
    assert first_tie + 2 < max(reference["answers"]), "the cut must leave duels to resume"
    cut = tmp_path / "cut.mcap"
    cut_before(bag, cut, first_tie + 2)
    assert first_tie in answers_of(cut) and first_tie + 2 not in answers_of(cut)
    resumed = tmp_path / "resumed.mcap"
    assert cli_main(["run", "--resume", str(cut), "--bag", str(resumed), "--no-progress"]) == 0
    assert answers_of(resumed) == reference["answers"]
    report = verify(resumed)
    assert report.ok and report.candidates_checked == BUDGET, report.format()


def test_old_run_configs_read_as_no_ties(tmp_path: Path) -> None:
    """A config without the tie keys (every bag recorded before ties) is the paper's model."""
    committed = Path(__file__).resolve().parents[2] / "bags" / "swimmer_sobol_s0.mcap"
    config = load_run(committed).config
    assert "tie_threshold" not in config.options["oracle"]
    settings = settings_of(config)
    assert settings.tie_threshold == 0.0 and settings.indifference == 0.0
