"""``judge_node``: a person answers the duels in a web browser, instead of ``oracle_node``.

Subscribes ``/localpbo/run_config``, ``/localpbo/candidate``, ``/localpbo/episode_result``,
``/localpbo/duel_request``, ``/localpbo/incumbent``, ``/localpbo/status`` and
``/localpbo/speculative_candidate`` (a speculating optimizer's possible next candidates:
their episodes are replayed ahead, so the next duel's replays are ready when it is); publishes
``/localpbo/duel_outcome`` (with ``answer_seconds``) and ``/localpbo/status``.

It serves a page (:mod:`localpbo_ros.judge_web`) at ``http://<host>:<port>/<secret>/``: the
secret is made per run (``secrets.token_urlsafe``) and kept in the run's folder under
``state_dir`` next to the answer journal, so a restarted judge serves the same path. The
address is logged and written to ``url_file``. The page shows the current duel's candidates
A and B (parameter values; for MuJoCo tasks their episodes replayed side by side,
:mod:`localpbo_ros.rollouts`), which candidate is being evaluated while results are missing,
progress, the incumbent and the answers so far, and takes "A better", "B better", "can't
tell" and "skip" once both episode results are in. What counts as recorded, resuming, and the
answer time: :mod:`localpbo_ros.judge`.

The page binds to 127.0.0.1 unless ``host`` names another address and ``allow_remote`` is
true (anyone who can reach the port and knows the URL can answer).

**The same address after a restart**: the port is kept in the run's folder next to the
secret; a judge started with ``port`` 0 (a free one) for a run it has served before moves to
that port when it is free, so a tab left open reconnects by itself (its event stream retries
every second). ``name`` is recorded with every answer whose page names nobody.
"""

from __future__ import annotations

import contextlib
import ipaddress
import os
import queue
import secrets
import threading
from pathlib import Path
from typing import Any, NoReturn, Unpack

from localpbo_msgs_py import (
    DecodeError,
    DecodeReason,
    Incumbent,
    RunConfig,
    Status,
    topics,
)
from localpbo_ros.base import NodeOptions
from localpbo_ros.driver import problem_of
from localpbo_ros.episode_process import EpisodeProcess
from localpbo_ros.follower import FollowerNode
from localpbo_ros.judge import MAX_NAME, Journal, JudgeCore, is_simulated
from localpbo_ros.judge_web import JudgeWeb
from localpbo_ros.params import Param, ParameterError
from localpbo_ros.rollouts import RolloutCache

DEFAULT_STATE_DIR = "~/.local/state/localpbo/judge"
AHEAD_QUEUE = 8
"""Speculative candidates waiting for their episode to be replayed ahead, at most."""
REPLAY_NICENESS = 10
"""Nice value added to the process that replays episodes for the page: a replay illustrates a
duel, while the simulator's episodes ahead open the next one (the answer buttons wait for
its result), so on a busy machine replays give way."""

PARAMS = [
    Param("host", "127.0.0.1", "Address the page binds to (loopback unless allow_remote)."),
    Param(
        "allow_remote",
        False,
        "Allow a host that is not a loopback address (anyone reaching it with the URL answers).",
    ),
    Param("port", 0, "TCP port of the page; 0 = a free one.", int_range=(0, 65535)),
    Param(
        "state_dir",
        DEFAULT_STATE_DIR,
        "Folder of the answer journals and URL secrets (one sub-folder per run).",
    ),
    Param("url_file", "", "File the page's URL is written to; empty = <state_dir>/url."),
    Param(
        "name",
        "",
        "The judging person's name, recorded with each answer (the page may set its own).",
    ),
    Param(
        "frame_stride",
        4,
        "Control steps between two frames of a replayed episode.",
        int_range=(1, 1000),
    ),
    Param(
        "rollout_cache",
        16,
        "Replayed episodes kept in memory (least recently used dropped).",
        int_range=(0, 1000),
    ),
    Param(
        "max_connections",
        16,
        "HTTP requests handled at once (more are closed at once).",
        int_range=(1, 256),
    ),
]


def check_host(host: str, allow_remote: bool) -> str:
    """``host`` if it is a loopback address (or ``localhost``), or any address with
    ``allow_remote``; ParameterError otherwise."""
    if host == "localhost":
        return "127.0.0.1"
    try:
        address = ipaddress.ip_address(host)
    except ValueError:
        raise ParameterError("host", f"{host[:80]!r} is not an IP address") from None
    if not address.is_loopback and not allow_remote:
        raise ParameterError(
            "host",
            f"{host} is not a loopback address; set allow_remote:=true to serve the page to "
            "other hosts",
        )
    return host


class JudgeNode(FollowerNode):
    """The judge node (see module docstring)."""

    def __init__(self, **options: Unpack[NodeOptions]) -> None:
        super().__init__("judge_node", PARAMS, **options)
        host = check_host(self.settings["host"], self.settings["allow_remote"])
        self.state_dir = Path(os.path.expanduser(self.settings["state_dir"]))
        url_file = self.settings["url_file"]
        self.url_file = Path(os.path.expanduser(url_file)) if url_file else self.state_dir / "url"
        self.url = ""
        self._pub = self.publisher(topics.DUEL_OUTCOME)
        self.core = JudgeCore(
            lambda outcome: self._pub.publish(outcome.encode()),
            self.drop,
            max_pending=self.settings["max_pending"],
            judge_name=self.settings["name"][:MAX_NAME],
        )
        self._rollouts: RolloutCache | None = None
        # the replays, off this process's interpreter lock and behind the episodes ahead
        self._episodes = EpisodeProcess(niceness=REPLAY_NICENESS)
        try:
            self.web = JudgeWeb(
                self.core,
                self.drop,
                self.rollout,
                host=host,
                port=self.settings["port"],
                max_connections=self.settings["max_connections"],
            )
        except OSError as exc:
            port = self.settings["port"]
            raise ParameterError("port", f"cannot serve on {host}:{port}: {exc}") from None
        self.subscribe(topics.CANDIDATE, self._on_candidate)
        self.subscribe(topics.EPISODE_RESULT, self._on_result)
        self.subscribe(topics.DUEL_REQUEST, self._on_request)
        self.subscribe(topics.INCUMBENT, self._on_incumbent)
        self.subscribe(topics.STATUS, self._on_status)
        # episodes a speculating optimizer may ask next: replayed ahead in one worker thread
        self._ahead: queue.Queue[tuple[int, tuple[float, ...]] | None] = queue.Queue(AHEAD_QUEUE)
        self._ahead_thread = threading.Thread(
            target=self._replay_ahead, name="judge-rollouts-ahead", daemon=True
        )
        self._ahead_thread.start()
        self.subscribe(topics.SPECULATIVE_CANDIDATE, self._on_speculative)

    # ------------------------------------------------------------------ plumbing
    def drop(self, reason: str, detail: str) -> None:
        """Count and warn (throttled); called from the executor and the web threads."""
        with self.core.lock:
            super().drop(reason, detail)

    def counter_snapshot(self) -> dict[str, int]:
        """The node's and the judge's counters (answers, skips, ...), copied under the lock
        the web threads count under."""
        with self.core.lock:
            return {**self.counters, **self.core.counters}

    def status_info(self) -> dict[str, str]:
        """The page's port (the URL's secret stays off the topics and the bag)."""
        return {"port": str(self.web.port)}

    def close(self) -> None:
        """Stop serving the page."""
        self.web.close()
        with contextlib.suppress(queue.Full):
            self._ahead.put_nowait(None)
        self._episodes.close()

    def _on_speculative(self, msg: object) -> None:
        """A candidate a prepared branch would propose: replay its episode ahead (dropped,
        counted, when ``AHEAD_QUEUE`` are already waiting)."""
        if self.config is None or self._rollouts is None:
            return
        cand = self.candidate(msg)
        if cand is None:
            return
        try:
            self._ahead.put_nowait((cand.candidate_id, cand.theta))
        except queue.Full:
            self.counters["rollouts_ahead_dropped"] += 1

    def _replay_ahead(self) -> None:
        while (item := self._ahead.get()) is not None:
            rollouts = self._rollouts
            if rollouts is not None:
                with contextlib.suppress(Exception):  # the page's request reports errors
                    rollouts.get(*item)

    def episode_return(self, candidate_id: int) -> float | None:
        """The episode return received for a candidate (for ``localpbo run``'s summary)."""
        return self.core.episode_return(candidate_id)

    def rollout(self, candidate_id: int) -> dict[str, Any] | None:
        """Candidate ``candidate_id``'s replayed episode (web threads)."""
        with self.core.lock:
            rollouts = self._rollouts
            cand = self.core.candidates.get(candidate_id)
        if rollouts is None or cand is None:
            return None
        return rollouts.get(candidate_id, cand.theta)

    # ------------------------------------------------------------------ run
    def reset(self) -> None:
        """Forget the previous run (its journal stays on disk)."""
        self.core.reset()
        self._rollouts = None
        self.url = ""

    def adopt(self, config: RunConfig) -> None:
        """Open the run's journal and secret, and publish the page's URL."""
        problem = problem_of(config)
        simulated = is_simulated(problem)
        if simulated:
            stride = self.settings["frame_stride"]
            episodes = self._episodes
            self._rollouts = RolloutCache(
                problem,
                config.seed,
                stride=stride,
                max_entries=self.settings["rollout_cache"],
                recorder=lambda cid, native: episodes.record(config, cid, native, stride),
            )
            episodes.warm(config)
        journal = Journal(self.state_dir / config.run_id)
        secret = journal.secret(lambda: secrets.token_urlsafe(24))
        self._keep_port(journal)
        answered = self.core.adopt(config, journal, secret, simulated=simulated)
        self.url = self.web.url()
        self.url_file.parent.mkdir(parents=True, exist_ok=True, mode=0o700)
        fd = os.open(self.url_file, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
        try:
            os.write(fd, (self.url + "\n").encode())
        finally:
            os.close(fd)
        self.get_logger().info(
            f"judge the duels of run {config.run_id} at {self.url} "
            f"({answered} answers journaled in {journal.path})"
        )

    def _keep_port(self, journal: Journal) -> None:
        """Serve on the run's former port when this judge took a free one (see module
        docstring); remember the port in use."""
        former = journal.port()
        if self.settings["port"] == 0 and former is not None and former != self.web.port:
            try:
                moved = JudgeWeb(
                    self.core,
                    self.drop,
                    self.rollout,
                    host=self.web.host,
                    port=former,
                    max_connections=self.settings["max_connections"],
                )
            except OSError as exc:
                self.get_logger().warning(
                    f"the run's former port {former} is taken ({exc}); serving on "
                    f"{self.web.port}: reopen the page at its new address"
                )
            else:
                self.web.close()
                self.web = moved
        try:
            journal.keep_port(self.web.port)
        except OSError as exc:
            self.drop("journal_failed", f"cannot keep the port: {exc}")

    # ------------------------------------------------------------------ callbacks
    def _on_candidate(self, msg: object) -> None:
        cand = self.admitted(self._on_candidate, self.candidate, msg)
        if cand is not None:
            self.core.on_candidate(cand)

    def _on_result(self, msg: object) -> None:
        res = self.admitted(self._on_result, self.result, msg)  # a candidate id in range
        if res is None:
            return
        for outcome in self.core.on_result(res):
            self._pub.publish(outcome.encode())

    def _on_request(self, msg: object) -> None:
        req = self.admitted(self._on_request, self.request, msg)  # ids in the run's range
        if req is None:
            return
        stored = self.core.on_request(req)
        if stored is not None:
            self._pub.publish(stored.encode())

    def _on_incumbent(self, msg: object) -> None:
        if self.hold(self._on_incumbent, msg):
            return
        config = self.config
        assert config is not None
        inc = Incumbent.decode(msg, expected_run_id=config.run_id, expected_dim=config.dim)
        if isinstance(inc, DecodeError):
            self.drop_decode(inc)
            return
        self.core.on_incumbent(inc)

    def _on_status(self, msg: object) -> None:
        if self.config is None:
            return  # reports of nodes before the run is known say nothing about it
        status = Status.decode(msg, expected_run_id=self.config.run_id)
        if isinstance(status, DecodeError):
            if status.reason is not DecodeReason.WRONG_RUN:
                self.drop_decode(status)
            return
        self.core.on_status(status)


def main(argv: list[str] | None = None) -> NoReturn:
    """``ros2 run localpbo_ros judge_node [--ros-args -p port:=8765]``."""
    from localpbo_ros.entry import run_node

    run_node(JudgeNode, argv, stop_when_finished=False)


if __name__ == "__main__":
    main()
