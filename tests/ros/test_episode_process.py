"""The episode process (localpbo_ros.episode_process): the same returns and replays as the
nodes compute in-process, bit for bit; a worker killed mid-episode fails visibly and the next
call starts a new one; SIGINT does not reach it; it ends when its parent is SIGKILLed."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import threading
import time

import numpy as np
import psutil
import pytest
from localpbo_ros.driver import problem_of
from localpbo_ros.episode_process import EpisodeProcess, EpisodeProcessError

from localpbo_core.seeds import episode_seed
from localpbo_core.session import evaluate_native

from .configs import run_config

CONFIG = run_config(run_id="ep", algorithm="sobol", task="hopper", seed=7, budget=10)


def _thetas(n: int) -> list[tuple[float, ...]]:
    rng = np.random.default_rng(3)
    lo, hi = np.asarray(CONFIG.lower), np.asarray(CONFIG.upper)
    return [tuple(float(v) for v in lo + (hi - lo) * rng.random(lo.size)) for _ in range(n)]


@pytest.fixture
def episodes():
    proc = EpisodeProcess()
    yield proc
    proc.close()


def test_returns_and_replays_are_those_computed_in_process(episodes: EpisodeProcess) -> None:
    problem = problem_of(CONFIG)
    for cid, theta in enumerate(_thetas(4)):
        seed = episode_seed(CONFIG.seed, cid)
        here = evaluate_native(problem, np.asarray(theta), seed)
        assert episodes.evaluate(CONFIG, cid, theta) == here  # bit-identical
        rec = episodes.record(CONFIG, cid, theta, 3)
        local = problem.record_native(np.asarray(theta), seed, 3)
        assert rec.episode.steps == local.episode.steps
        assert np.array_equal(rec.frames, local.frames)
    assert episodes.worker_pid() != os.getpid()


def test_an_episode_that_raises_raises_its_error(episodes: EpisodeProcess) -> None:
    with pytest.raises(ValueError):
        episodes.evaluate(CONFIG, 0, (1e9,) * CONFIG.dim)  # outside the task's box


def test_a_killed_worker_fails_the_call_and_the_next_call_starts_another(
    episodes: EpisodeProcess,
) -> None:
    first = episodes.worker_pid()
    theta = _thetas(1)[0]
    errors: list[BaseException] = []

    def long_calls() -> None:
        try:
            for cid in range(200):
                episodes.evaluate(CONFIG, cid, theta)
        except BaseException as exc:
            errors.append(exc)

    caller = threading.Thread(target=long_calls)
    caller.start()
    time.sleep(0.3)  # mid-episode
    os.kill(first, signal.SIGKILL)
    caller.join(60)
    assert len(errors) == 1 and isinstance(errors[0], EpisodeProcessError), errors
    second = episodes.worker_pid()
    assert second != first
    problem = problem_of(CONFIG)
    assert episodes.evaluate(CONFIG, 5, theta) == evaluate_native(
        problem, np.asarray(theta), episode_seed(CONFIG.seed, 5)
    )


def test_sigint_does_not_reach_the_worker(episodes: EpisodeProcess) -> None:
    pid = episodes.worker_pid()
    os.kill(pid, signal.SIGINT)  # a Ctrl-C reaches the whole process group
    time.sleep(0.3)
    assert episodes.worker_pid() == pid


def test_calls_after_close_fail() -> None:
    proc = EpisodeProcess()
    proc.worker_pid()
    proc.close()
    with pytest.raises(EpisodeProcessError):
        proc.evaluate(CONFIG, 0, _thetas(1)[0])


def test_the_worker_ends_when_its_parent_is_killed() -> None:
    script = textwrap.dedent(
        """
        import sys, time
        from localpbo_ros.episode_process import EpisodeProcess
        proc = EpisodeProcess(niceness=5)
        print(proc.worker_pid(), flush=True)
        time.sleep(600)
        """
    )
    parent = subprocess.Popen([sys.executable, "-c", script], stdout=subprocess.PIPE, text=True)
    try:
        assert parent.stdout is not None
        worker = psutil.Process(int(parent.stdout.readline()))
        assert worker.nice() == os.nice(0) + 5
    finally:
        parent.kill()
        parent.wait(10)
    worker.wait(timeout=10)  # within PARENT_CHECK_S (plus a loaded machine's slack)
