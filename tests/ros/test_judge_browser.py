"""The judge's page in a real headless browser (selenium + Debian's chromium/chromedriver):
a whole ``localpbo run --oracle human`` answered by keyboard and buttons, with a skip, a
reload and two tabs answering the same duel; the bag then holds each answer once and
verifies."""

from __future__ import annotations

import os
import shutil
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest
from localpbo_ros.bagtools import duel_timings, load_run
from localpbo_ros.replay import verify
from localpbo_ros.suite import run_suite

from localpbo_msgs_py import OutcomeKind

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


class Run:
    """``run_suite`` with a judge in a thread; ``url`` once the page is served."""

    def __init__(self, tmp_path: Path, run_id: str, evaluator: Any = None, **extra: Any) -> None:
        self.bag = tmp_path / f"{run_id}.mcap"
        self.urls: list[str] = []
        self.result: dict[str, Any] = {}
        settings = {**SETTINGS, "run_id": run_id, **extra}

        def go() -> None:
            try:
                self.result["summary"] = run_suite(
                    settings,
                    self.bag,
                    judge={"state_dir": str(tmp_path / "judge")},
                    on_url=self.urls.append,
                    timeout_s=90,
                    evaluator=evaluator,
                )
            except BaseException as exc:  # reported by the test
                self.result["error"] = exc

        self.thread = threading.Thread(target=go, daemon=True)
        self.thread.start()
        until(lambda: bool(self.urls) or not self.thread.is_alive(), 20)
        assert self.urls, self.result
        self.url = self.urls[0]

    def finish(self) -> Any:
        self.thread.join(60)
        assert not self.thread.is_alive()
        assert "error" not in self.result, self.result["error"]
        return self.result["summary"]


def until(pred: Callable[[], Any], timeout: float) -> Any:
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        value = pred()
        if value:
            return value
        time.sleep(0.05)
    raise AssertionError("condition not met in time")


def duel_shown(driver: Any, *, settle: bool = True) -> int:
    """The duel the page shows once its answer buttons are enabled (and, with ``settle``,
    once an answer would not count as a double press of the previous one)."""

    def ready() -> int | None:
        enabled = driver.find_element("id", "answer-a").is_enabled()
        duel = driver.execute_script("return state && state.duel && state.duel.duel_id")
        calm = not settle or driver.execute_script("return settled()")
        return None if not enabled or duel is None or not calm else int(duel) + 1

    return until(ready, 20) - 1


def reply_text(driver: Any, *needles: str) -> str:
    return until(
        lambda: (
            (t := driver.find_element("id", "reply").text) and all(n in t for n in needles) and t
        ),
        10,
    )


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

    until(lambda: "thank you" in browser.find_element("id", "phase").text.lower(), 20)
    history = browser.find_elements("css selector", "#history tbody tr")
    assert len(history) == 5
    summary = run.finish()
    assert summary.state == "done" and summary.duels == 5

    # the bag: every answer exactly once, as given, with its answer time; it verifies
    recorded = load_run(run.bag)
    assert sorted(o.duel_id for o in recorded.outcomes) == sorted(answers)
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
    for _ in range(5):  # finish the run
        duel = duel_shown(browser)
        browser.find_element("id", "answer-a").click()
        reply_text(browser, f"Recorded: duel {duel}")
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
    for _ in range(2):
        duel = duel_shown(browser)
        browser.find_element("id", "answer-a").click()
        reply_text(browser, f"Recorded: duel {duel}")
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
    outcomes = load_run(run.bag).outcomes
    ids = [o.duel_id for o in outcomes]
    assert len(ids) == len(set(ids))
    assert [o.duel_id for o in outcomes if o.kind is OutcomeKind.INDIFFERENT] == [tied]
    assert verify(run.bag).ok
