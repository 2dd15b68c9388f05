"""A message the run published but the bag lacks fails ``replay --verify``, naming it; bag-info
shows every node's last status (its drop counters) and the recorder's accounting."""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
from localpbo_ros.commands import main as commands_main
from localpbo_ros.completeness import (
    PUBLISHED_CANDIDATES,
    PUBLISHED_DUELS,
    format_ids,
    last_statuses,
    parse_ids,
)
from localpbo_ros.replay import verify
from localpbo_ros.suite import run_suite

from localpbo_msgs_py import CandidateMsg, DuelOutcome, DuelRequest
from localpbo_msgs_py.bag import BagMessage, BagWriter, read_messages
from localpbo_msgs_py.topics import CANDIDATE, DUEL_OUTCOME, DUEL_REQUEST, STATUS

from .conftest import SMALL_TASK

BUDGET = 30
SETTINGS = {
    "algorithm": "sobol",
    "task": "swimmer",
    "budget": BUDGET,
    "seed": 5,
    "run_id": "whole",
    "task_options": json.dumps(SMALL_TASK),
}


@pytest.fixture(scope="module")
def bag(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("completeness") / "run.mcap"
    summary = run_suite(SETTINGS, path, timeout_s=120)
    assert summary.state == "done" and summary.evaluations == BUDGET
    return path


def copy_without(src: Path, dst: Path, leave_out: Callable[[BagMessage], bool]) -> int:
    """Copy ``src`` to ``dst`` leaving out the messages ``leave_out`` picks; their number."""
    left = 0
    with BagWriter(dst) as writer:
        writer.add_suite_topics()
        for rec in read_messages(src):
            if leave_out(rec):
                left += 1
                continue
            writer.copy(rec)
    return left


def duel_id(rec: BagMessage, topic: str) -> int | None:
    if rec.topic != topic:
        return None
    codec: Any = DuelRequest if topic == DUEL_REQUEST.name else DuelOutcome
    decoded = codec.decode(rec.message)
    return decoded.duel_id if isinstance(decoded, codec) else None


def candidate_id(rec: BagMessage) -> int | None:
    if rec.topic != CANDIDATE.name:
        return None
    decoded = CandidateMsg.decode(rec.message)
    return decoded.candidate_id if isinstance(decoded, CandidateMsg) else None


def test_the_whole_bag_verifies_and_the_optimizer_says_what_it_published(bag: Path) -> None:
    report = verify(bag)
    assert report.ok, report.format()
    optimizer = last_statuses(bag, "whole")["optimizer_node"]
    assert optimizer.info[PUBLISHED_CANDIDATES] == f"0-{BUDGET - 1}"
    assert optimizer.info[PUBLISHED_DUELS] == f"0-{BUDGET - 2}"


def test_verify_names_the_last_duel_requests_missing_from_the_bag(
    bag: Path, tmp_path: Path
) -> None:
    """The finding: the optimizer's last five duel requests gone from the bag."""
    cut = tmp_path / "cut.mcap"
    last = BUDGET - 2

    def last_five(rec: BagMessage) -> bool:
        did = duel_id(rec, DUEL_REQUEST.name)
        return did is not None and did > last - 5

    assert copy_without(bag, cut, last_five) >= 5
    report = verify(cut)
    assert not report.ok
    assert f"duel requests {last - 4}-{last} were published but are not in the bag" in (
        report.mismatch
    )
    assert report.format().startswith("MISMATCH")


def test_verify_finds_requests_lost_with_their_outcomes(bag: Path, tmp_path: Path) -> None:
    """Requests and outcomes both gone (the rebuilt run then just looks shorter): only the
    optimizer's own account shows them."""
    cut = tmp_path / "cut.mcap"

    def tail(rec: BagMessage) -> bool:
        for topic in (DUEL_REQUEST.name, DUEL_OUTCOME.name):
            did = duel_id(rec, topic)
            if did is not None and did >= 20:
                return True
        return False

    copy_without(bag, cut, tail)
    report = verify(cut)
    assert not report.ok and f"duel requests 20-{BUDGET - 2} were published" in report.mismatch


def test_verify_names_a_missing_candidate(bag: Path, tmp_path: Path) -> None:
    cut = tmp_path / "cut.mcap"
    assert copy_without(bag, cut, lambda rec: candidate_id(rec) == 7) >= 1
    report = verify(cut)
    assert not report.ok
    assert "candidates 7 were published but are not in the bag" in report.mismatch
    assert "candidates 7 are in duel requests" not in report.mismatch  # named once


def test_without_the_optimizer_status_the_bag_still_checks_itself(
    bag: Path, tmp_path: Path
) -> None:
    """No optimizer status (an older bag): an outcome without its request still shows."""
    cut = tmp_path / "cut.mcap"

    def request_3_and_statuses(rec: BagMessage) -> bool:
        return rec.topic == STATUS.name or duel_id(rec, DUEL_REQUEST.name) == 3

    copy_without(bag, cut, request_3_and_statuses)
    report = verify(cut)
    assert not report.ok
    assert "duel requests 3 have outcomes but are not in the bag" in report.mismatch


def test_bag_info_shows_every_node_and_the_recorder(
    bag: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert commands_main(["bag-info", str(bag)]) == 0
    out = capsys.readouterr().out
    assert "nodes (last status in the bag):" in out
    lines = {line.split()[0]: line for line in out.splitlines() if line.startswith("  ")}
    for node in ("optimizer_node", "sim_node", "oracle_node", "recorder_node"):
        assert node in lines, out
    assert f"episodes {BUDGET}" in lines["sim_node"]
    assert "recorder:" in out and "0 foreign messages recorded" in out
    assert "capped" not in out


@pytest.mark.parametrize(
    ("ids", "text"),
    [
        ([], ""),
        ([3], "3"),
        ([0, 1, 2, 3], "0-3"),
        ([5, 0, 1, 2, 7, 8, 10], "0-2,5,7-8,10"),
    ],
)
def test_id_ranges_round_trip(ids: list[int], text: str) -> None:
    assert format_ids(ids) == text
    assert parse_ids(text) == set(ids)


def test_long_id_lists_keep_their_latest_ranges() -> None:
    ids = list(range(0, 4000, 2))
    text = format_ids(ids, limit=100)
    assert text.startswith("+") and len(text) <= 100
    assert parse_ids(text) <= set(ids) and 3998 in parse_ids(text)
    with pytest.raises(ValueError, match="bad id range"):
        parse_ids("5-2")
