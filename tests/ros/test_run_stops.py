"""``localpbo run`` stopped by SIGINT or SIGTERM, as a user's Ctrl-C or a supervisor would:
at random points while it starts (importing), while it runs, and while a bridged run has a
controller's gains changed. Every time: exit code 128 + the signal, no traceback, and either
no bag (stopped before the run started) or a complete bag that ``--resume`` continues to the
same run an uninterrupted one makes; a bridged controller has its own gains back."""

from __future__ import annotations

import json
import random
import re
import signal
import subprocess
import sys
import threading
import time
import urllib.error
import urllib.request
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import IO

import pytest
from localpbo_examples.pid_controller_node import BRIDGE_SETTINGS
from localpbo_ros.bagtools import load_run
from localpbo_ros.replay import verify

from localpbo_msgs_py.bag import summarize

from .processes import host_env, imported_before_guard, interrupt, wait_for_guard

LOCALPBO = str(Path(sys.executable).with_name("localpbo"))
REPO = Path(__file__).resolve().parents[2]
PID_SPACE = REPO / "ros_ws/src/localpbo_examples/config/pid_space.yaml"
TASK = ["--algorithm", "sobol"]
"""Sobol on Swimmer's full episodes (about 50 ms each): a stop after k evaluations lands well
before the run's end even on an idle machine."""
BUDGET = 40
PROGRESS = re.compile(r"(\d+)/(\d+)")


class Run:
    """A ``localpbo run`` process; stderr (the progress bar) and stdout read on threads."""

    def __init__(self, args: list[str], env: dict[str, str]) -> None:
        self.popen = subprocess.Popen(
            [LOCALPBO, "run", *args],
            env=env,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        self.out: list[str] = []
        self.err: list[str] = []
        self.changed = threading.Condition()
        assert self.popen.stdout is not None and self.popen.stderr is not None
        self._readers = [
            threading.Thread(target=self._read, args=(s, buf), daemon=True)
            for s, buf in ((self.popen.stdout, self.out), (self.popen.stderr, self.err))
        ]
        for reader in self._readers:
            reader.start()

    def _read(self, stream: IO[str], buf: list[str]) -> None:
        while chunk := stream.read(1):
            with self.changed:
                buf.append(chunk)
                self.changed.notify_all()

    def evaluations(self) -> int:
        found = PROGRESS.findall("".join(self.err))
        return int(found[-1][0]) if found else 0

    def wait_evaluations(self, n: int, timeout: float = 300.0) -> None:
        with self.changed:
            ok = self.changed.wait_for(
                lambda: self.evaluations() >= n or self.popen.poll() is not None, timeout
            )
        assert ok and self.popen.poll() is None, self.text()

    def finish(self, timeout: float = 120.0) -> int:
        try:
            code = self.popen.wait(timeout)
        except subprocess.TimeoutExpired:
            self.popen.kill()
            self.popen.wait()
            raise AssertionError(
                f"localpbo run did not stop within {timeout} s\n{self.text()}"
            ) from None
        for reader in self._readers:
            reader.join(10)
        return code

    def text(self) -> str:
        return "stdout:\n" + "".join(self.out) + "\nstderr:\n" + "".join(self.err)

    def kill(self) -> None:
        if self.popen.poll() is None:
            self.popen.kill()
            self.popen.wait()


def assert_stopped(run: Run, code: int, sig: signal.Signals) -> None:
    assert code == 128 + sig, (code, run.text())
    assert "Traceback" not in run.text(), run.text()


def resume_and_check(bag: Path, tmp_path: Path, env: dict[str, str], *extra: str) -> Path:
    """Continue ``bag`` to the end; the new bag verifies and holds the whole budget."""
    resumed = tmp_path / f"{bag.stem}-resumed.mcap"
    cmd = [LOCALPBO, "run", "--resume", str(bag), "--bag", str(resumed), "--no-progress", *extra]
    done = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stdout + done.stderr
    report = verify(resumed)
    assert report.ok, report.format()
    return resumed


@pytest.fixture(scope="module")
def reference(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The same run, never stopped."""
    bag = tmp_path_factory.mktemp("reference") / "ref.mcap"
    cmd = [LOCALPBO, "run", *TASK, "--budget", str(BUDGET), "--run-id", "stops"]
    cmd += ["--bag", str(bag), "--no-progress"]
    done = subprocess.run(cmd, env=host_env(64), capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stdout + done.stderr
    return bag


def thetas(bag: Path) -> dict[int, tuple[float, ...]]:
    return {cid: tuple(c.theta) for cid, c in load_run(bag).candidates.items()}


@contextmanager
def busy_cores(n: int) -> Iterator[None]:
    """``n`` busy processes: both cores loaded by others."""
    busy = [subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(n)]
    try:
        yield
    finally:
        for proc in busy:
            proc.kill()
            proc.wait()


@pytest.mark.parametrize(
    ("sig", "seed", "second", "busy"),
    [
        (signal.SIGINT, 0, None, 0),
        (signal.SIGTERM, 1, None, 0),
        (signal.SIGINT, 2, signal.SIGINT, 0),  # a second Ctrl-C while it stops
        (signal.SIGTERM, 3, signal.SIGINT, 4),  # and both cores loaded by other processes
    ],
    ids=["sigint", "sigterm", "sigint-twice", "sigterm-then-sigint-loaded"],
)
def test_stop_while_running_then_resume(
    sig: signal.Signals,
    seed: int,
    second: signal.Signals | None,
    busy: int,
    tmp_path: Path,
    reference: Path,
) -> None:
    rng = random.Random(seed)
    bag = tmp_path / "stops.mcap"
    env = host_env(65 + seed)
    with busy_cores(busy):
        run = Run([*TASK, "--budget", str(BUDGET), "--run-id", "stops", "--bag", str(bag)], env)
        try:
            run.wait_evaluations(rng.randint(2, BUDGET // 2))
            time.sleep(rng.uniform(0.0, 0.3))
            run.popen.send_signal(sig)
            if second is not None:
                time.sleep(rng.uniform(0.0, 0.2))
                run.popen.send_signal(second)  # ignored: the first one's stop goes on
            code = run.finish()
        finally:
            run.kill()
    if second is not None and second != sig and code == 128 + second:
        # both arrived before Python ran a handler (the main thread was inside a long C call
        # on the loaded machine): Python runs them in signal-number order, so the stop is the
        # other one's; still one stop, with that signal's code
        sig = second
    assert_stopped(run, code, sig)
    out = "".join(run.out)
    assert f"run stops: stopped ({sig.name}; continue it with: localpbo run --resume" in out
    info = summarize(bag)
    assert info.complete, info.format()
    stopped_at = len(load_run(bag).candidates)
    assert 0 < stopped_at < BUDGET, out  # stopped in the middle
    resumed = resume_and_check(bag, tmp_path, env)
    # the stop changed nothing: the continued run is the uninterrupted one, bit for bit
    assert thetas(resumed) == thetas(reference)


@pytest.mark.parametrize(("seed", "after_s"), list(enumerate([0.0, 0.5, 1.5, 3.0, 3.0])))
def test_stop_while_starting(seed: int, after_s: float, tmp_path: Path) -> None:
    """Signalled from the start guard on (importing, creating the nodes, the first
    evaluations; ``after_s`` plus up to 0.3 s of jitter): a clean stop whatever the point (no
    bag, or a complete one that ``--resume`` continues). Full Swimmer episodes (about 50 ms
    each), so the 60 evaluations outlast the first 3.3 s even on an idle machine."""
    rng = random.Random(100 + seed)
    sig = (signal.SIGINT, signal.SIGTERM)[seed % 2]
    bag = tmp_path / "early.mcap"
    env = {**host_env(69), "PYTHONPROFILEIMPORTTIME": "1"}
    args = ["--algorithm", "sobol", "--budget", "60", "--run-id", "early", "--bag", str(bag)]
    run = Run(args, env)
    try:
        wait_for_guard(run.popen.pid)
        time.sleep(after_s + rng.uniform(0.0, 0.3))
        run.popen.send_signal(sig)
        code = run.finish()
    finally:
        run.kill()
    # the guard came before numpy, torch, rclpy and MuJoCo were imported
    assert imported_before_guard("".join(run.err)) == []
    assert_stopped(run, code, sig)
    if bag.exists():  # the run had started: complete and resumable
        assert summarize(bag).complete
        resume_and_check(bag, tmp_path, host_env(69))
    else:
        err = "".join(run.err)
        assert (
            f"localpbo: stopped by {sig.name} while starting" in err
            or f"stopped by {sig.name} before the run started; no bag written" in err
        ), run.text()


READ_GAINS = """
import json
from localpbo_ros.dds import host_scope
host_scope()
import rclpy
from rcl_interfaces.srv import GetParameters
from rclpy.node import Node
rclpy.init()
node = Node("gain_reader")
client = node.create_client(GetParameters, "/pid_controller_node/get_parameters")
assert client.wait_for_service(timeout_sec=60), "no parameter service"
future = client.call_async(GetParameters.Request(names=["kp", "ki", "kd"]))
rclpy.spin_until_future_complete(node, future, timeout_sec=60)
print(json.dumps([v.double_value for v in future.result().values]))
"""


def read_gains(env: dict[str, str]) -> list[float]:
    """The controller's gains, read through its parameter service (as ``ros2 param get``)."""
    done = subprocess.run(
        [sys.executable, "-c", READ_GAINS], env=env, capture_output=True, text=True, timeout=120
    )
    assert done.returncode == 0, done.stdout + done.stderr
    return list(json.loads(done.stdout.strip().splitlines()[-1]))


@pytest.mark.parametrize(
    ("sig", "seed"), [(signal.SIGINT, 0), (signal.SIGTERM, 1)], ids=["sigint", "sigterm"]
)
def test_stop_bridged_run_restores_the_controller(
    sig: signal.Signals, seed: int, tmp_path: Path
) -> None:
    rng = random.Random(200 + seed)
    env = host_env(71 + seed)
    # 3 s per trial (300 steps at 10 ticks/s), so the stop lands inside a trial
    command = [sys.executable, "-m", "localpbo_examples.pid_controller_node"]
    controller = subprocess.Popen(
        [*command, "--ros-args", "-p", "rate_hz:=10.0"],
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
    )
    lines: list[str] = []
    seen = threading.Condition()

    def read() -> None:
        assert controller.stdout is not None
        for line in controller.stdout:
            with seen:
                lines.append(line)
                seen.notify_all()

    threading.Thread(target=read, daemon=True).start()
    bag = tmp_path / "bridged.mcap"
    bridge = json.dumps(BRIDGE_SETTINGS)
    args = ["--space", str(PID_SPACE), "--bridge", bridge, "--algorithm", "sobol"]
    args += ["--budget", "6", "--run-id", "bridged", "--bag", str(bag), "--no-progress"]
    run = None
    try:
        with seen:
            assert seen.wait_for(lambda: any(" ready" in x for x in lines), 120), lines
        original = read_gains(env)
        run = Run(args, env)
        with seen:
            changed = seen.wait_for(lambda: any("gains set: kp=" in x for x in lines), 300)
        assert changed, "".join(lines) + run.text()
        time.sleep(rng.uniform(0.0, 2.5))
        assert run.popen.poll() is None, run.text()
        run.popen.send_signal(sig)
        code = run.finish(timeout=180)
        assert_stopped(run, code, sig)
        assert read_gains(env) == original, "".join(lines)
        assert summarize(bag).complete
        bag_thetas = thetas(bag)
        assert 0 < len(bag_thetas) < 6
        resume_and_check(bag, tmp_path, env, "--bridge", bridge)
        assert read_gains(env) == original  # and back again after the resumed run
    finally:
        if run is not None:
            run.kill()
        interrupt(controller, 30)


URL = re.compile(r"judge the duels at (http://\S+)")


def page_url(run: Run, timeout: float = 300.0) -> str:
    """The judge page's URL, once ``localpbo run --oracle human`` printed it."""
    with run.changed:
        found = run.changed.wait_for(
            lambda: URL.search("".join(run.out)) is not None or run.popen.poll() is not None,
            timeout,
        )
    match = URL.search("".join(run.out))
    assert found and match, run.text()
    return match.group(1)


def serves(url: str) -> bool:
    try:
        with urllib.request.urlopen(url, timeout=10) as response:
            return bool(response.status == 200)
    except (urllib.error.URLError, ConnectionError, TimeoutError):
        return False


@pytest.mark.parametrize(
    ("sig", "seed"), [(signal.SIGINT, 0), (signal.SIGTERM, 1)], ids=["sigint", "sigterm"]
)
def test_stop_a_person_judging_then_resume(sig: signal.Signals, seed: int, tmp_path: Path) -> None:
    """``--oracle human``: stopped while the page waits for a person, then resumed (the page
    comes back) and stopped again."""
    rng = random.Random(300 + seed)
    env = host_env(73 + seed)
    bag = tmp_path / "judged.mcap"
    args = ["--oracle", "human", *TASK]
    run = Run([*args, "--budget", "20", "--run-id", "judged", "--bag", str(bag)], env)
    try:
        url = page_url(run)
        assert serves(url), run.text()
        time.sleep(rng.uniform(0.0, 1.0))
        run.popen.send_signal(sig)
        code = run.finish()
    finally:
        run.kill()
    assert_stopped(run, code, sig)
    assert not serves(url)  # the page stopped with the run
    assert summarize(bag).complete
    assert load_run(bag).config.run_id == "judged"
    resumed = tmp_path / "judged-resumed.mcap"
    again = Run(["--resume", str(bag), "--bag", str(resumed)], env)
    try:
        assert serves(page_url(again)), again.text()
        again.popen.send_signal(sig)
        code = again.finish()
    finally:
        again.kill()
    assert_stopped(again, code, sig)
    assert summarize(resumed).complete
