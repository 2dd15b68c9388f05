"""The committed bag (bags/README.md): summary, offline verification, CLI exit codes, play."""

from __future__ import annotations

from collections import Counter
from pathlib import Path

from localpbo_ros.bagtools import load_run
from localpbo_ros.commands import main as cli_main
from localpbo_ros.replay import play
from rclpy.node import Node
from rosbags.highlevel import AnyReader

from localpbo_msgs_py import DuelOutcome
from localpbo_msgs_py.topics import DUEL_OUTCOME, RUN_CONFIG

BAG = Path(__file__).resolve().parents[2] / "bags" / "swimmer_sobol_s0.mcap"


def test_committed_bag_is_a_complete_run() -> None:
    run = load_run(BAG)
    assert run.complete and run.config.task == "swimmer" and run.config.algorithm == "sobol"
    assert len(run.candidates) == run.config.budget == 40
    assert Counter(o.duel_id for o in run.outcomes) == Counter(range(39))
    with AnyReader([BAG]) as reader:  # independent reader
        topics = {c.topic: c.msgtype for c in reader.connections}
    assert topics[RUN_CONFIG.name] == "std_msgs/msg/String"


def test_cli_bag_info_and_verify(capsys) -> None:
    assert cli_main(["bag-info", str(BAG)]) == 0
    out = capsys.readouterr().out
    assert "file complete: yes (closed cleanly)" in out and "/localpbo/duel_outcome" in out
    assert "run finished: yes (40 of 40 evaluations)" in out
    assert "decision time: not recorded" in out  # recorded before requests carried it
    assert "outcomes: 39 duels, 39 decisive, 0 can't tell, 0 failed" in out
    assert cli_main(["replay", "--verify", str(BAG)]) == 0
    assert capsys.readouterr().out.startswith("OK: 40 candidates and 39 duels")
    assert cli_main(["bag-info", str(BAG.with_suffix(".missing"))]) == 2


def test_play_committed_bag_filtered(ros) -> None:
    got = ros.collect(DUEL_OUTCOME)
    player = ros.add(Node("player", context=ros.ctx, start_parameter_services=False))
    sent = play(BAG, player, ros.executor, rate=20.0, topics=[DUEL_OUTCOME.name])
    assert ros.spin_until(lambda: len(got) == 39, 5)
    assert sent == 39
    recorded = [o for o in load_run(BAG).outcomes]
    assert [DuelOutcome.decode(m) for m in got] == recorded


def test_cli_replay_plays(monkeypatch, capsys) -> None:
    from localpbo_ros.dds import PROFILE_FILE

    # keep the process-wide DDS settings the CLI would choose out of later tests
    monkeypatch.setenv("ROS_AUTOMATIC_DISCOVERY_RANGE", "OFF")
    monkeypatch.setenv("FASTRTPS_DEFAULT_PROFILES_FILE", str(PROFILE_FILE))
    code = cli_main(
        ["replay", str(BAG), "--rate", "50", "--topics", RUN_CONFIG.name, DUEL_OUTCOME.name]
    )
    assert code == 0
    assert f"published 40 messages from {BAG}" in capsys.readouterr().out
    assert cli_main(["replay", str(BAG), "--topics", "/nope"]) == 2
