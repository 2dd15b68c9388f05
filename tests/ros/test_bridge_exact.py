"""Every score ``param_bridge_node`` records is its trial's own, under load and when the
target dies.

The target is ``localpbo_ros.benchmarks.thermal_controller``, written as a user would write
one (not the shipped example): a free-running PID loop that publishes a cost at every step,
also between trials and after its done message. README's command (``localpbo run --space …
--bridge …``) tunes it while other processes keep both cores busy, in each scoring mode, and
every recorded score is compared with the trial's own cost computed offline from the
candidate's gains:

* ``trial_samples`` and ``done_topic``: exactly the mean cost of the first N steps after the
  reset;
* ``trial_duration_s``: exactly the mean cost of the first k steps after the reset for one k
  (a sample of another trial in the window would match no such prefix).

Then the target is SIGKILLed at random points of trials and restarted: no trial it was in
the middle of may be scored ``ok``.
"""

from __future__ import annotations

import json
import random
import signal
import subprocess
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from localpbo_ros.benchmarks.bridge_exactness import (
    BRIDGE,
    LOCALPBO,
    MODES,
    SPACE,
    busy,
    environment,
    is_exact,
    recorded,
    run_command,
    start_controller,
)

from localpbo_msgs_py.bag import read_messages
from localpbo_msgs_py.topics import EPISODE_RESULT


@pytest.fixture
def load() -> Iterator[None]:
    """Four busy processes: both cores loaded by others for the whole test."""
    with busy(4):
        yield


def scored(bag: Path) -> bool:
    """Whether the (growing) bag holds an episode result yet."""
    try:
        return any(True for _ in read_messages(bag, topics=[EPISODE_RESULT.name]))
    except Exception:  # not yet a readable file
        return False


def run(tmp_path: Path, env: dict[str, str], mode: str, budget: int) -> Path:
    space = tmp_path / "thermal.yaml"
    space.write_text(SPACE)
    bag = tmp_path / f"{mode}.mcap"
    done = subprocess.run(
        run_command(space, bag, mode, budget), env=env, capture_output=True, text=True, timeout=600
    )
    assert done.returncode == 0, done.stdout + done.stderr
    return bag


@pytest.mark.parametrize("mode", list(MODES))
def test_every_score_is_its_trials_own_under_load(tmp_path: Path, load: None, mode: str) -> None:
    env = environment(93 + list(MODES).index(mode))
    controller = start_controller(env)
    try:
        bag = run(tmp_path, env, mode, budget=10)
    finally:
        controller.kill()
        controller.wait()
    thetas, results = recorded(bag)
    ok = [r for r in results if r.status.value == "ok"]
    assert len({r.candidate_id for r in ok}) == 10  # the run completed: every candidate scored
    for res in results:
        cid = res.candidate_id
        if res.status.value == "failed":  # visibly: a starved target may fall silent
            assert "no score sample for" in res.error, (cid, res.error)
            continue
        assert res.episode_return is not None
        assert is_exact(mode, thetas[cid], res.episode_return), (cid, res.episode_return)


def test_a_target_killed_mid_trial_never_gives_ok(tmp_path: Path, load: None) -> None:
    """SIGKILL at random points of 20 trials (the target restarted each time): each trial that
    was under way when its target died fails; every ``ok`` is exact."""
    env = environment(97)
    rng = random.Random(7)
    kills = 0
    controller = start_controller(env)
    space = tmp_path / "thermal.yaml"
    space.write_text(SPACE)
    bag = tmp_path / "kill.mcap"
    bridge = {**BRIDGE, **MODES["done"], "trial_duration_s": 5.0, "service_timeout_s": 1.0}
    cmd = [
        LOCALPBO, "run", "--space", str(space), "--budget", "200", "--seed", "2",
        "--run-id", "kill", "--bag", str(bag), "--bridge", json.dumps(bridge),
        "--failure-policy", "retry", "--max-retries", "100", "--no-progress",
    ]  # fmt: skip
    runner = subprocess.Popen(cmd, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT)
    try:
        deadline = time.monotonic() + 900
        while runner.poll() is None and time.monotonic() < deadline and not scored(bag):
            time.sleep(0.2)  # the run has started (the target was checked and took a trial)
        while kills < 20 and runner.poll() is None and time.monotonic() < deadline:
            time.sleep(rng.uniform(0.05, 0.6))  # a trial: ~0.25 s of samples + its checks
            controller.kill()
            controller.wait()
            kills += 1
            controller = start_controller(env)
        time.sleep(2.0)  # trials on the last instance
    finally:
        controller.kill()
        controller.wait()
        runner.send_signal(signal.SIGINT)
        out, _ = runner.communicate(timeout=60)
    assert kills == 20 and bag.exists(), out
    thetas, results = recorded(bag)
    failed = [r for r in results if r.status.value == "failed"]
    assert len(failed) >= 5, "kills land in trials or their checks"
    ok = [r for r in results if r.status.value == "ok"]
    assert ok, out
    for res in ok:
        assert res.episode_return is not None
        assert is_exact("done", thetas[res.candidate_id], res.episode_return), res.candidate_id


def refused_run(tmp_path: Path, env: dict[str, str], space: str, **bridge: Any) -> Any:
    (tmp_path / "s.yaml").write_text(space)
    bag = tmp_path / "refused.mcap"
    cmd = [
        LOCALPBO, "run", "--space", str(tmp_path / "s.yaml"), "--budget", "6",
        "--bag", str(bag), "--no-progress", "--bridge", json.dumps({**BRIDGE, **bridge}),
    ]  # fmt: skip
    t0 = time.monotonic()
    done = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=120)
    assert not bag.exists() and not list(tmp_path.glob("*.mcap")), "a refused run leaves no bag"
    assert "evaluations" not in done.stdout
    return done, time.monotonic() - t0


def test_a_parameter_the_target_lacks_is_refused_by_name_before_the_run(tmp_path: Path) -> None:
    env = environment(98)
    controller = start_controller(env)
    try:
        space = SPACE.replace("name: kd,", "name: kf,")  # kp, ki exist; kf does not
        done, _ = refused_run(tmp_path, env, space)
    finally:
        controller.kill()
        controller.wait()
    assert done.returncode == 2, done.stderr
    assert "target.kf" in done.stderr and "no parameter 'kf'" in done.stderr, done.stderr
    assert "target.kp" not in done.stderr and "Traceback" not in done.stderr


def test_an_absent_target_is_refused_within_its_wait(tmp_path: Path) -> None:
    done, seconds = refused_run(tmp_path, environment(99), SPACE, target_wait_s=1.0)
    assert done.returncode == 2, done.stderr
    assert "target_node" in done.stderr and "/thermal has no parameter services" in done.stderr
    assert seconds < 30, seconds  # start-up included; the wait itself is 1 s
