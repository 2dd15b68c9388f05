"""Nothing lost: a restarted judge resumes at the open duel under the same URL, and a stopped
run resumed from its bag keeps every answer exactly once (journaled answers are not asked
again). Answers go over HTTP here; the browser tests drive the page itself."""

from __future__ import annotations

import json
import time
import urllib.error
import urllib.request
from collections.abc import Callable
from pathlib import Path
from typing import Any

from localpbo_ros.bagtools import load_run
from localpbo_ros.judge import Journal
from localpbo_ros.judge_node import JudgeNode
from localpbo_ros.optimizer_node import OptimizerNode
from localpbo_ros.replay import verify
from localpbo_ros.sim_node import SimNode
from localpbo_ros.suite import run_suite

from localpbo_msgs_py import DuelOutcome

from .judged_suite import JudgedSuite, answers_once_each

SETTINGS = {
    "algorithm": "sobol",
    "task": "swimmer",
    "budget": 7,
    "seed": 2,
    "task_options": '{"episode_steps": 50, "value_range": 50.0}',
}


def fetch(url: str, data: bytes | None = None) -> tuple[int, Any]:
    req = urllib.request.Request(url, data=data)
    try:
        with urllib.request.urlopen(req, timeout=10) as r:
            return r.status, json.loads(r.read())
    except urllib.error.HTTPError as err:
        return err.code, json.loads(err.read())


def ready_duel(url: str, timeout: float = 20.0, spin: Callable[[], Any] | None = None) -> Any:
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if spin is not None:
            spin()
        duel = fetch(url + "api/state")[1].get("duel")
        if duel is not None and duel["ready"]:
            return duel
        time.sleep(0.02)
    raise AssertionError("no duel ready in time")


def answer(url: str, duel: Any, choice: str) -> Any:
    body = {"duel_id": duel["duel_id"], "first_id": duel["a"]["id"], "second_id": duel["b"]["id"]}
    status, reply = fetch(url + "api/answer", json.dumps({**body, "choice": choice}).encode())
    assert status == 200, reply
    return reply


def test_restarted_judge_resumes_at_the_open_duel(ros, tmp_path: Path) -> None:
    state_dir = str(tmp_path / "judge")
    opt = OptimizerNode(
        context=ros.ctx,
        overrides={**SETTINGS, "run_id": "restart", "republish_period_s": 0.2},
    )
    ros.add(SimNode(context=ros.ctx))
    judge = ros.add(JudgeNode(context=ros.ctx, overrides={"state_dir": state_dir}))
    ros.add(opt)
    assert ros.spin_until(lambda: bool(judge.url), 10.0)
    url = judge.url

    def spin() -> None:
        ros.spin_for(0.03)

    first = ready_duel(url, spin=spin)
    answer(url, first, "a")
    second = ready_duel(url, spin=spin)
    assert second["duel_id"] == first["duel_id"] + 1
    judge.close()
    ros.remove(judge)  # the judge dies with duel 1 open
    judge = ros.add(JudgeNode(context=ros.ctx, overrides={"state_dir": state_dir}))
    assert ros.spin_until(lambda: bool(judge.url), 10.0)
    assert judge.url.split("/")[3] == url.split("/")[3]  # the same secret
    url = judge.url
    again = ready_duel(url, spin=spin)  # learnt from the re-published request
    assert (again["duel_id"], again["a"]["id"], again["b"]["id"]) == (
        second["duel_id"],
        second["a"]["id"],
        second["b"]["id"],
    )
    assert fetch(url + "api/state")[1]["progress"]["answered"] == 1
    while not opt.finished:
        answer(url, ready_duel(url, spin=spin), "b")
        ros.spin_until(lambda: opt.finished or bool(judge.core.open), 10.0)
    assert opt.state == "done"
    assert [o.duel_id for o in opt.driver.accepted] == list(range(opt.driver.n_duels))
    judge.close()


def test_resumed_run_keeps_every_answer_once(tmp_path: Path) -> None:
    bag = tmp_path / "resumable.mcap"
    judge = {"state_dir": str(tmp_path / "judge")}
    settings = {**SETTINGS, "run_id": "resumable"}
    first_part = JudgedSuite(settings, bag, judge, timeout_s=6)
    given: dict[int, DuelOutcome] = {}
    for choice in ("a", "b"):
        duel = ready_duel(first_part.url)
        answer(first_part.url, duel, choice)
    assert first_part.finish(30).state == "timeout"  # stopped with duel 2 open
    first = load_run(bag)
    given = {o.duel_id: o for o in first.outcomes}
    assert sorted(given) == [0, 1]
    # an answer that reached the journal but not the bag (the run died in between)
    pending = first.requests[2]
    journaled = DuelOutcome.decisive(pending, pending.second_id, answer_seconds=3.0)
    Journal(tmp_path / "judge" / "resumable").append(journaled)

    second_bag = tmp_path / "resumed.mcap"
    second_part = JudgedSuite(settings, second_bag, judge, resume=bag, timeout_s=60)
    asked: list[int] = []
    while second_part.thread.is_alive():
        try:
            state = fetch(second_part.url + "api/state")[1]
        except OSError:  # the run ended and the page with it
            break
        duel = state.get("duel")
        if duel is not None and duel["ready"] and duel["duel_id"] not in asked:
            asked.append(duel["duel_id"])
            answer(second_part.url, duel, "a")
        time.sleep(0.02)
    resumed = second_part.finish(30)
    assert resumed.state == "done"
    assert 2 not in asked and asked == list(range(3, resumed.duels))
    out = load_run(second_bag)
    each = answers_once_each(out.outcomes)  # a repeat only ever the same answer
    assert sorted(each) == list(range(resumed.duels))
    assert {i: o for i, o in each.items() if i < 2} == given
    assert each[2] == journaled
    assert verify(second_bag).ok


def test_cli_run_oracle_human_prints_the_url_and_waits(tmp_path: Path, capsys) -> None:
    import subprocess
    import sys

    from localpbo_ros.commands import main

    argv = ["run", "--oracle", "human", "--task", "swimmer", "--algorithm", "sobol"]
    argv += ["--budget", "4", "--seed", "1", "--task-options", SETTINGS["task_options"]]
    argv += ["--out", str(tmp_path), "--run-id", "cli", "--no-progress"]
    proc = subprocess.Popen(
        [sys.executable, "-m", "localpbo_ros.commands", *argv],
        stdout=subprocess.PIPE,
        stderr=subprocess.DEVNULL,
        text=True,
    )
    try:
        assert proc.stdout is not None
        printed = ""
        while "judge the duels at " not in printed:
            line = proc.stdout.readline()
            assert line, "the command ended without printing the URL"
            printed += line
        url = printed.split("judge the duels at ", 1)[1].split()[0]
        assert url.startswith("http://127.0.0.1:") and url.endswith("/")
        answered = 0
        while proc.poll() is None:
            try:
                duel = ready_duel(url, timeout=5)
            except (AssertionError, OSError):
                break
            answer(url, duel, "b")
            answered += 1
        assert proc.wait(30) == 0 and answered == 3
    finally:
        if proc.poll() is None:
            proc.kill()
    assert (tmp_path / "judge" / "cli" / "answers.jsonl").read_text().count("\n") == 3
    capsys.readouterr()
    assert main(["bag-info", str(tmp_path / "cli.mcap")]) == 0
    assert "answer time: 3 duels, median " in capsys.readouterr().out
    # a refused judge parameter names it and leaves no bag behind
    bad = ["run", "--oracle", "human", "--judge", '{"host": "0.0.0.0"}', "--no-progress"]
    assert main([*bad, "--out", str(tmp_path / "bad")]) == 2
    assert "invalid parameter 'host'" in capsys.readouterr().err
    assert list((tmp_path / "bad").iterdir()) == []


def test_run_refused_when_the_judge_folder_holds_another_run(tmp_path: Path) -> None:
    settings = {**SETTINGS, "run_id": "reused"}
    judge = {"state_dir": str(tmp_path / "judge")}
    folder = tmp_path / "judge" / "reused"
    folder.mkdir(parents=True)
    (folder / "run_config.json").write_text('{"run_id": "reused", "seed": 99}')
    summary = run_suite(settings, tmp_path / "reused.mcap", judge=judge, timeout_s=20)
    assert summary.state == "failed" and "judge_node" in summary.error
