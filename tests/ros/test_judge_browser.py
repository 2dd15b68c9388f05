"""The judge's page in a real headless browser (selenium + Debian's chromium/chromedriver):
a whole ``localpbo run --oracle human`` answered by keyboard and buttons, with a skip, a
reload and two tabs answering the same duel; the bag then holds each answer once and
verifies."""

from __future__ import annotations

import json
import os
import shutil
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from localpbo_ros.bagtools import duel_timings, load_run
from localpbo_ros.benchmarks.judge_screenshot import until
from localpbo_ros.driver import rebuild
from localpbo_ros.replay import verify

from localpbo_msgs_py import OutcomeKind

from .judged_suite import JudgedSuite, answers_once_each

CHROMIUM = shutil.which("chromium") or "/usr/bin/chromium"
CHROMEDRIVER = shutil.which("chromedriver") or "/usr/bin/chromedriver"

pytestmark = pytest.mark.skipif(
    not (Path(CHROMIUM).exists() and Path(CHROMEDRIVER).exists()) and not os.environ.get("CI"),
    reason="needs Debian's chromium and chromium-driver (.ci/run installs them)",
)

SETTINGS = {
    "algorithm": "sobol",
    "task": "swimmer",
    "budget": 6,  # 2 initial points + 4: five duels, one at a time
    "seed": 4,
    "task_options": '{"episode_steps": 200, "value_range": 50.0}',
}


@pytest.fixture(scope="module")
def browser() -> Iterator[Any]:
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    options = webdriver.ChromeOptions()
    options.binary_location = CHROMIUM
    for arg in ("--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage"):
        options.add_argument(arg)
    options.add_argument("--window-size=1280,1100")
    driver = webdriver.Chrome(service=Service(CHROMEDRIVER), options=options)
    driver.set_page_load_timeout(20)
    yield driver
    driver.quit()


class Run(JudgedSuite):
    """This module's run ``run_id`` with a judge (``SETTINGS`` updated by ``extra``)."""

    def __init__(self, tmp_path: Path, run_id: str, evaluator: Any = None, **extra: Any) -> None:
        super().__init__(
            {**SETTINGS, "run_id": run_id, **extra},
            tmp_path / f"{run_id}.mcap",
            {"state_dir": str(tmp_path / "judge")},
            timeout_s=90,
            evaluator=evaluator,
        )


def duel_shown(driver: Any, *, settle: bool = True) -> int:
    """The duel the page shows once its answer buttons are enabled (and, with ``settle``,
    once an answer would not count as a double press of the previous one)."""

    def ready() -> int | None:
        enabled = driver.find_element("id", "answer-a").is_enabled()
        duel = driver.execute_script("return state && state.duel && state.duel.duel_id")
        calm = not settle or driver.execute_script("return settled()")
        return None if not enabled or duel is None or not calm else int(duel) + 1

    return until(ready, 20) - 1


def answer_a(driver: Any, times: int) -> None:
    """Answer ``a`` to each of the next ``times`` duels the page shows, once it records it."""
    for _ in range(times):
        duel = duel_shown(driver)
        driver.find_element("id", "answer-a").click()
        reply_text(driver, f"Recorded: duel {duel}")


def reply_text(driver: Any, *needles: str) -> str:
    return until(
        lambda: (
            (t := driver.find_element("id", "reply").text) and all(n in t for n in needles) and t
        ),
        10,
    )


def refused_text(driver: Any) -> str:
    """The page's line for keys and clicks it did not take."""
    return until(lambda: driver.find_element("id", "refused").text, 10)


def press(driver: Any, key: str) -> None:
    from selenium.webdriver.common.action_chains import ActionChains

    ActionChains(driver).send_keys(key).perform()


def test_whole_run_answered_in_the_browser(browser: Any, tmp_path: Path) -> None:
    from selenium.webdriver.common.keys import Keys

    run = Run(tmp_path, "judged", tie_threshold=0.0)  # a run without "can't tell"
    browser.get(run.url)
    answers: dict[int, str] = {}

    # duel 0: keyboard "a"; the page shows both rollouts and the parameters by name
    duel = duel_shown(browser)
    until(lambda: browser.find_element("id", "canvas-a").is_displayed(), 10)
    until(lambda: browser.find_element("id", "canvas-b").is_displayed(), 10)
    rows = browser.find_elements("css selector", "#params tbody tr")
    assert len(rows) == 16 and rows[0].get_attribute("textContent").startswith("W[motor1_rot")
    assert "Keys" in browser.find_element("tag name", "footer").text
    assert not browser.find_element("id", "answer-tie").is_enabled()  # no ties in this run
    before = browser.execute_script("return JSON.stringify(state)")
    press(browser, "a")
    reply_text(browser, f"Recorded: duel {duel}", "A better")
    answers[duel] = "A better"
    # a state polled before the answer landed, shown late, never re-opens the answered duel
    # (one synchronous script: no poll can land between rendering and reading)
    enabled, phase = browser.execute_script(
        "state = JSON.parse(arguments[0]); render();"
        "return [!$('answer-a').disabled, $('phase').textContent];",
        before,
    )
    assert not enabled and f"Duel {duel} is recorded" in phase
    browser.execute_script("refresh();")

    # duel 1: skip (no other duel waits, so it comes back), reload, then the B button
    duel = duel_shown(browser)
    press(browser, "s")
    reply_text(browser, f"Skipped duel {duel}", "comes back")
    browser.refresh()
    assert duel_shown(browser) == duel
    assert "asked again" in browser.find_element("id", "phase").text
    browser.find_element("id", "answer-b").click()
    reply_text(browser, f"Recorded: duel {duel}", "B better")
    answers[duel] = "B better"

    # duel 2: two tabs; the first answer wins, the second tab is told
    duel = duel_shown(browser)
    first_tab = browser.current_window_handle
    browser.switch_to.new_window("tab")
    browser.get(run.url + "?push=0&refresh=60000")  # this tab does not refresh on its own
    assert duel_shown(browser) == duel
    second_tab = browser.current_window_handle
    browser.switch_to.window(first_tab)
    press(browser, Keys.ARROW_LEFT)
    reply_text(browser, f"Recorded: duel {duel}", "A better")
    answers[duel] = "A better"
    browser.switch_to.window(second_tab)
    browser.find_element("id", "answer-b").click()
    told = reply_text(browser, "Not recorded (HTTP 409", "already answered")
    assert "A better" in told
    browser.close()
    browser.switch_to.window(first_tab)

    # the rest: arrow right, then "b"
    for key in (Keys.ARROW_RIGHT, "b"):
        duel = duel_shown(browser)
        press(browser, key)
        reply_text(browser, f"Recorded: duel {duel}", "B better")
        answers[duel] = "B better"

    try:  # long: the first torch import (the run's recommendation) can take 30 s under load
        until(lambda: "thank you" in browser.find_element("id", "phase").text.lower(), 90)
    except TimeoutError:
        shown = browser.execute_script("return [$('phase').textContent, JSON.stringify(state)]")
        run.thread.join(90)
        ended = run.result.get("summary") or run.result.get("error")
        raise AssertionError(f"the page never said thank you: {shown[0]}; run: {ended}") from None
    history = browser.find_elements("css selector", "#history tbody tr")
    assert len(history) == 5
    summary = run.finish()
    assert summary.state == "done" and summary.duels == 5

    # the bag: every answer as given (a repeat only ever the same), with its answer time; it
    # verifies
    recorded = load_run(run.bag)
    assert sorted(answers_once_each(recorded.outcomes)) == sorted(answers)
    for out in recorded.outcomes:
        assert out.kind is OutcomeKind.DECISIVE
        said = "A better" if out.winner_id == out.first_id else "B better"
        assert said == answers[out.duel_id]
        assert out.answer_seconds is not None and 0 <= out.answer_seconds < 60
    report = verify(run.bag)
    assert report.ok, report.format()
    timings = {t.name: t for t in duel_timings(recorded)}
    assert len(timings["answer time"].seconds) == 5
    assert timings["answer time"].format().startswith("answer time: 5 duels, median ")


def test_wrong_secret_and_malformed_answer_refused_in_the_browser(
    browser: Any, tmp_path: Path
) -> None:
    run = Run(tmp_path, "refusals")
    base, _, _ = run.url.rstrip("/").rpartition("/")
    browser.get(base + "/not-the-secret/")
    assert "not found" in browser.find_element("tag name", "body").text
    browser.get(run.url)
    duel = duel_shown(browser)
    status = browser.execute_async_script(
        """const done = arguments[arguments.length - 1];
        fetch("api/answer", {method: "POST", body: JSON.stringify(
            {duel_id: state.duel.duel_id, first_id: state.duel.b.id,
             second_id: state.duel.a.id, choice: "a"})})
          .then(async (r) => done([r.status, await r.json()]));"""
    )
    assert status[0] == 400
    assert (status[1]["field"], status[1]["reason"]) == ("first_id", "wrong_candidates")
    assert duel_shown(browser) == duel  # nothing recorded
    answer_a(browser, 5)  # finish the run
    summary = run.finish()
    assert summary.state == "done"
    assert len(load_run(run.bag).outcomes) == 5


def test_page_says_which_candidate_is_being_evaluated(browser: Any, tmp_path: Path) -> None:
    """A slow evaluator (a robot's trial): the page names the candidate being evaluated and
    offers the answers only once both results are in."""

    def slow(config: Any, candidate_id: int, theta: Any) -> float:
        time.sleep(1.5)
        return float(sum(theta))

    run = Run(tmp_path, "robot", evaluator=slow, budget=3, task="hartmann6", task_options="{}")
    browser.get(run.url)
    phase = until(
        lambda: (t := browser.find_element("id", "phase").text).startswith("Evaluating") and t, 20
    )
    assert "candidate" in phase and "once both results are in" in phase
    assert not browser.find_element("id", "answer-a").is_enabled()
    assert not browser.find_element("id", "answer-b").is_enabled()
    assert "evaluating" in browser.find_element("id", "side-a").get_attribute(
        "class"
    ) or "evaluating" in browser.find_element("id", "side-b").get_attribute("class")
    assert browser.find_element("id", "canvas-a").is_displayed() is False  # nothing to replay
    answer_a(browser, 2)
    assert run.finish().state == "done"


def test_cant_tell_in_the_browser(browser: Any, tmp_path: Path) -> None:
    from selenium.webdriver.common.keys import Keys

    run = Run(tmp_path, "ties")  # a judged run takes "can't tell" unless told otherwise
    browser.get(run.url)
    duel = duel_shown(browser)
    assert browser.find_element("id", "answer-tie").is_enabled()
    press(browser, Keys.ARROW_DOWN)
    reply_text(browser, f"Recorded: duel {duel}", "can't tell")
    tied = duel

    def next_step() -> str:
        if "thank you" in browser.find_element("id", "phase").text.lower():
            return "over"
        return "answer" if browser.find_element("id", "answer-a").is_enabled() else ""

    while until(next_step, 20) == "answer":
        duel = duel_shown(browser)
        press(browser, "a")
        reply_text(browser, f"Recorded: duel {duel}")
    summary = run.finish()
    assert summary.state == "done"
    outcomes = answers_once_each(load_run(run.bag).outcomes).values()
    assert [o.duel_id for o in outcomes if o.kind is OutcomeKind.INDIFFERENT] == [tied]
    assert verify(run.bag).ok


def test_first_hopper_duel_is_watchable_at_a_chosen_speed(browser: Any, tmp_path: Path) -> None:
    """README's command for a person on Hopper: the first duel's two episodes last >= 1 s on
    screen and move; the speed control (0.25x-4x) is remembered, A and B share one clock, and
    the replay loops."""
    import argparse

    from localpbo_ros.commands import add_subcommands, run_settings

    parser = argparse.ArgumentParser()
    add_subcommands(parser.add_subparsers())
    args = parser.parse_args(["run", "--task", "hopper", "--oracle", "human", "--budget", "3"])
    settings = run_settings(args)
    assert json.loads(settings["task_options"])["around_ars"] > 0  # a person starts at ARS
    settings = {**settings, "run_id": "hop-watch", "algorithm": "sobol", "speculate": False}
    run = Run(tmp_path, "hop-watch", **{k: v for k, v in settings.items() if k != "run_id"})
    browser.get(run.url)
    duel_shown(browser)
    until(lambda: browser.execute_script("return !!(replay.a && replay.b)"), 30)
    goal = browser.find_element("id", "goal").text
    assert goal.startswith("Better = hops farther forward")
    for side in ("a", "b"):
        seconds, screen, moved = browser.execute_script(
            f"const r = replay.{side};"
            "const f0 = JSON.stringify(r.frames[0]);"
            "const f1 = JSON.stringify(r.frames[r.frames.length - 1]);"
            "return [episodeSeconds(r), duration() / effectiveRate(), f0 !== f1];"
        )
        assert (seconds >= 1.0 or screen >= 1.0) and moved, (side, seconds, screen)
    # the speed: 4x, remembered across a reload; 0.25x slows the clock
    from selenium.webdriver.support.ui import Select

    Select(browser.find_element("id", "speed")).select_by_value("4")
    assert browser.execute_script("return speed") == 4
    browser.refresh()
    until(lambda: browser.execute_script("return !!(replay && replay.a && replay.b)"), 30)
    assert browser.execute_script("return speed") == 4
    assert browser.find_element("id", "speed").get_attribute("value") == "4"
    Select(browser.find_element("id", "speed")).select_by_value("0.25")
    browser.execute_script("restart()")
    t0 = browser.execute_script("return now()")
    time.sleep(1.0)
    t1 = browser.execute_script("return now()")
    assert 0.15 <= t1 - t0 <= 0.5  # a quarter of the screen time
    # both canvases are drawn from one clock: both show the same t
    labels = browser.execute_script("return [replay.a.dt, replay.b.dt]")
    assert labels[0] == labels[1]
    # loop: at the end the replay starts again by itself
    Select(browser.find_element("id", "speed")).select_by_value("4")
    browser.execute_script("replay.offset = duration() - 0.01; replay.start = performance.now();")
    until(lambda: browser.execute_script("return now() < duration() / 2"), 5)
    answer_a(browser, 2)
    assert run.finish().state == "done"


def test_keys_never_lost_and_layout_kept(browser: Any, tmp_path: Path) -> None:
    """Arrow keys answer even when the time slider has the focus; a double press and a key
    while no duel is ready are refused with a message; the duel section never hides between
    duels (the old one dims with 'preparing')."""
    from selenium.webdriver.common.keys import Keys

    run = Run(tmp_path, "keys", tie_threshold=0.0)
    browser.get(run.url)
    duel = duel_shown(browser)
    until(lambda: browser.find_element("id", "player").is_displayed(), 10)
    # watch the duel section across the answer: it never hides
    browser.execute_script(
        "window.hid = 0; new MutationObserver(() => { if ($('duel').hidden) hid += 1; })"
        ".observe($('duel'), {attributes: true});"
    )
    browser.find_element("id", "scrub").click()  # the slider takes the focus
    # a double press: the second is refused where the person looks, never silently dropped
    press(browser, Keys.ARROW_LEFT + Keys.ARROW_LEFT)
    reply_text(browser, f"Recorded: duel {duel}", "A better")
    told = refused_text(browser)
    # which reason depends on when the second key lands: while the first answer is sent,
    # after it was recorded but before the next duel shows, or once it shows (too soon)
    reasons = ("still being sent", "no duel is ready", "after your previous answer")
    assert "not taken" in told and any(reason in told for reason in reasons), told
    next_duel = duel_shown(browser)
    assert next_duel != duel
    for _ in range(4):  # the rest of the run, by keys
        duel = duel_shown(browser)
        press(browser, "a")
        reply_text(browser, f"Recorded: duel {duel}")
    until(lambda: "thank you" in browser.find_element("id", "phase").text.lower(), 20)
    assert browser.execute_script("return hid") == 0
    assert run.finish().state == "done"


def test_key_while_no_duel_is_ready_is_refused_visibly(browser: Any, tmp_path: Path) -> None:
    """A slow evaluator: keys pressed while the results are missing say why they were not
    taken."""

    def slow(config: Any, candidate_id: int, theta: Any) -> float:
        time.sleep(1.0)
        return float(sum(theta))

    run = Run(tmp_path, "slowkeys", evaluator=slow, budget=3, task="hartmann6", task_options="{}")
    browser.get(run.url)
    until(lambda: browser.execute_script("return !!(state && state.duel)"), 20)
    if not browser.execute_script("return state.duel.ready"):
        press(browser, "a")
        told = refused_text(browser)
        assert "waiting for its episode results" in told or "no duel is ready" in told
    for _ in range(2):
        duel = duel_shown(browser)
        press(browser, "b")
        reply_text(browser, f"Recorded: duel {duel}")
    assert run.finish().state == "done"


def test_note_name_history_replay_and_visible_time(browser: Any, tmp_path: Path) -> None:
    """A note and the judge's name go with the answer into the journal; the history lists
    them and replays a past duel; time while the page is hidden does not count."""
    run = Run(tmp_path, "notes", tie_threshold=0.0)
    browser.get(run.url)
    duel = duel_shown(browser)
    name = browser.find_element("id", "judge-name")
    name.clear()
    name.send_keys("Ada")
    note = browser.find_element("id", "answer-note")
    note.send_keys("A swims straighter; b")  # typing "b" in the note answers nothing
    assert not browser.find_element("id", "reply").text.startswith("Recorded")
    from selenium.webdriver.common.keys import Keys

    note.send_keys(Keys.ESCAPE)
    # hide the page for 1.5 s (the Page Visibility API as the browser reports it)
    browser.execute_script(
        "Object.defineProperty(document, 'visibilityState',"
        " {configurable: true, get: () => 'hidden'});"
        "document.dispatchEvent(new Event('visibilitychange'));"
    )
    time.sleep(1.5)
    browser.execute_script(
        "Object.defineProperty(document, 'visibilityState',"
        " {configurable: true, get: () => 'visible'});"
        "document.dispatchEvent(new Event('visibilitychange'));"
    )
    press(browser, "a")
    reply_text(browser, f"Recorded: duel {duel}", "A better")
    journal = tmp_path / "judge" / "notes" / "answers.jsonl"
    line = json.loads(journal.read_text().splitlines()[0])
    assert line["note"] == "A swims straighter; b" and line["judge"] == "Ada"
    assert line["hidden"] is True
    assert line["answer_seconds"] <= line["server_seconds"] - 1.4
    row = until(lambda: browser.find_elements("css selector", "#history tbody tr"), 10)[0]
    assert "A swims straighter" in row.text and "Ada" in row.text
    # replay the past duel; answers are off meanwhile; Esc goes back
    row.find_element("css selector", "button.history-replay").click()
    assert f"Reviewing duel {duel}" in browser.find_element("id", "review-text").text
    until(lambda: browser.execute_script("return !!(replay.a && replay.b)"), 10)
    assert not browser.find_element("id", "answer-a").is_enabled()
    press(browser, Keys.ESCAPE)
    until(lambda: not browser.find_element("id", "review").is_displayed(), 5)
    for _ in range(4):
        duel = duel_shown(browser)
        press(browser, "b")
        reply_text(browser, f"Recorded: duel {duel}")
    assert run.finish().state == "done"
    names = {json.loads(x)["judge"] for x in journal.read_text().splitlines()}
    assert names == {"Ada"}  # remembered on the page for every answer


def test_undo_in_the_browser_rebuilt_by_verify(browser: Any, tmp_path: Path) -> None:
    """'u' takes back the last answer: journaled, a retracted outcome in the bag, the duel
    asked again and answered anew; --verify rebuilds the run."""
    run = Run(tmp_path, "undo", tie_threshold=0.0)
    browser.get(run.url)
    first = duel_shown(browser)
    press(browser, "a")
    reply_text(browser, f"Recorded: duel {first}", "A better")
    second = duel_shown(browser)
    press(browser, "a")
    reply_text(browser, f"Recorded: duel {second}", "A better")
    until(lambda: browser.find_element("id", "undo").is_enabled(), 10)
    browser.execute_script("lastAnswerAt = -1e9;")
    press(browser, "u")
    reply_text(browser, f"Undone: duel {second}")
    # from the undo on, the duel asked after the taken-back answer is never offered
    offered = set()
    deadline = time.monotonic() + 10
    while time.monotonic() < deadline:
        shown = browser.execute_script(
            "return state && state.duel && !document.getElementById('answer-a').disabled"
            " ? state.duel.duel_id : null;"
        )
        if shown is not None:
            offered.add(shown)
            if shown == second:
                break
        time.sleep(0.01)
    assert offered == {second}, offered
    again = duel_shown(browser)
    assert again == second
    assert "undone" in browser.find_element("css selector", "#history tbody tr").text
    press(browser, "b")
    reply_text(browser, f"Recorded: duel {second}", "B better")
    while "thank you" not in browser.find_element("id", "phase").text.lower():
        try:
            duel = duel_shown(browser)
        except TimeoutError:
            break
        press(browser, "a")
        reply_text(browser, f"Recorded: duel {duel}")
    summary = run.finish()
    assert summary.state == "done"
    journal = (tmp_path / "judge" / "undo" / "answers.jsonl").read_text().splitlines()
    assert {"undo": second} == {k: v for k, v in json.loads(journal[2]).items() if k == "undo"}
    recorded = load_run(run.bag)
    kinds = [(o.duel_id, o.kind) for o in recorded.outcomes]
    assert (second, OutcomeKind.RETRACTED) in kinds
    final = {o.duel_id: o for o in recorded.outcomes if o.kind is OutcomeKind.DECISIVE}
    assert final[second].winner_id == final[second].second_id  # the answer given after undo
    report = verify(run.bag)
    assert report.ok, report.format()


def start_cli(*args: str) -> tuple[Any, list[str]]:
    """``localpbo run ARGS`` as its own process; its output lines as they come."""
    import subprocess
    import sys

    command = [sys.executable, "-m", "localpbo_ros.commands", "run", *args, "--no-progress"]
    proc = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    lines: list[str] = []

    def read() -> None:
        assert proc.stdout is not None
        for line in proc.stdout:
            lines.append(line)

    threading.Thread(target=read, daemon=True).start()
    return proc, lines


def printed_url(lines: list[str]) -> str:
    line = until(lambda: next((x for x in lines if "judge the duels at " in x), ""), 60)
    return line.split("judge the duels at ", 1)[1].split()[0]


def test_resume_keeps_the_person_and_the_open_tab(browser: Any, tmp_path: Path) -> None:
    """The run is killed (SIGKILL) with the tab open; ``localpbo run --resume BAG`` without
    --oracle continues with the person on the same URL, the tab reconnects without a reload,
    and the counts agree; --oracle simulated is refused naming the flag."""
    import signal

    out = str(tmp_path)
    options = '{"episode_steps": 200, "value_range": 50.0}'
    first, lines = start_cli(
        "--task", "swimmer", "--algorithm", "sobol", "--budget", "6", "--seed", "4",
        "--task-options", options, "--oracle", "human", "--out", out, "--run-id", "kept",
    )  # fmt: skip
    try:
        url = printed_url(lines)
        browser.get(url)
        browser.execute_script("window.sameTab = 42;")
        for _ in range(2):
            duel = duel_shown(browser)
            press(browser, "a")
            reply_text(browser, f"Recorded: duel {duel}")
        duel_shown(browser, settle=False)
    finally:
        first.send_signal(signal.SIGKILL)
        first.wait(30)
    until(lambda: "Lost contact" in browser.find_element("id", "phase").text, 20)
    bag = str(tmp_path / "kept.mcap")
    refused, said = start_cli("--resume", bag, "--oracle", "simulated", "--out", out)
    assert refused.wait(60) == 2
    until(lambda: any("--oracle human" in x for x in said), 5)
    second, lines = start_cli("--resume", bag, "--out", out)  # no --oracle: still the person
    try:
        assert printed_url(lines) == url
        answered = 2
        while True:
            try:
                duel = duel_shown(browser)
            except TimeoutError:
                break
            assert browser.execute_script("return window.sameTab") == 42  # never reloaded
            press(browser, "b")
            reply_text(browser, f"Recorded: duel {duel}")
            answered += 1
            if "thank you" in browser.find_element("id", "phase").text.lower():
                break
        assert second.wait(60) == 0, "".join(lines)
    finally:
        if second.poll() is None:
            second.kill()
    assert answered == 5
    progress = browser.find_element("id", "progress-text").text
    assert "you answered 5 duels · the optimizer counted 5" in progress, progress
    resumed = load_run(tmp_path / "kept-resumed.mcap")
    # the bag holds every outcome published: the judge sends a journaled answer again when a
    # request for it comes back (e.g. re-published before the answer arrived under load); a
    # repeat is the same answer, and the optimizer's acceptance rule counts each duel once
    assert sorted(answers_once_each(resumed.outcomes)) == list(range(5))
    rebuilt = rebuild(resumed.config, resumed.outcomes)
    assert rebuilt.driver.n_duels == 5
    assert rebuilt.refused == len(resumed.outcomes) - 5
    assert verify(tmp_path / "kept-resumed.mcap").ok


def test_short_episodes_are_slowed_down_to_be_seen(browser: Any, tmp_path: Path) -> None:
    """Hopper in the paper's box (--warm-start none): random policies fall within a fraction
    of a second; the page plays such a duel slowed to last >= 1.5 s on screen and says so."""
    run = Run(tmp_path, "short", task="hopper", budget=3, task_options="{}", speculate=False)
    browser.get(run.url)
    duel_shown(browser)
    until(lambda: browser.execute_script("return !!(replay.a && replay.b)"), 30)
    browser.execute_script("setSpeed(1)")
    total, rate = browser.execute_script("return [duration(), effectiveRate()]")
    assert total < 0.2  # seed 4: episodes of 0.08 s and 0.14 s
    assert abs(total / rate - 1.5) < 1e-6  # slowed to 1.5 s on screen
    assert "slowed to" in until(lambda: browser.find_element("id", "rate").text, 5)
    for _ in range(2):
        duel = duel_shown(browser)
        browser.find_element("id", "answer-b").click()
        reply_text(browser, f"Recorded: duel {duel}")
    assert run.finish().state == "done"
