"""The logic of ``judge_node``: a person answers the duels (no ROS and no HTTP here).

:class:`JudgeCore` keeps what the judge knows about its run (the run config, candidates,
episode results, open duel requests, the incumbent, the optimizer's progress) and turns the
page's answers into :class:`~localpbo_msgs_py.DuelOutcome` messages. It is shared by the
node's executor thread and the web server's threads, so every method takes one lock.

**Recorded.** An answer counts as recorded, and only then is it acknowledged to the page
(HTTP 200), once it is appended to the run's answer journal (``answers.jsonl``, one JSON
line per answer, flushed and ``fsync``-ed) *and* published on ``/localpbo/duel_outcome``.
The journal, not the optimizer's reaction, is the acknowledgement because the optimizer may
be gone when a person answers (killed, restarting, or resumed later with ``localpbo run
--resume``): what the journal holds is never asked again. Whenever a request for a journaled
duel arrives (the optimizer re-publishes its pending requests every ``republish_period_s``,
a resumed optimizer asks its first unanswered duel again) the stored outcome is published
again (unless it went out less than ``REPEAT_AFTER_S`` ago: a request re-published while the
answer was on its way), and the optimizer, which accepts an identical answer once and counts
the rest as duplicates, keeps each answer exactly once. So a judge restarted on the same
``state_dir``, a reloaded page or a resumed run continue at the first open duel; a killed run
loses no answer. Whether the optimizer took the answer shows on the page through its status
(``count.duels_done``).

**Answers** (:meth:`JudgeCore.answer`, the body of ``POST api/answer``): a JSON object
``{"duel_id", "first_id", "second_id", "choice"}``, choice ``a`` (the first candidate is
better), ``b`` (the second), ``tie`` (can't tell; only when the run takes ties) or ``skip``
(ask again later: the duel moves to the back of the queue). The first answer to a duel wins;
a later one gets 409 with the recorded answer. Malformed answers get 400 naming the field and
the reason; each refusal is counted (``dropped_http_<reason>``) by the node.

**Answer time** (``answer_seconds``): from the first time the duel was shown ready to answer
(both episode results in) until its answer, measured on this host's monotonic clock; a skip
does not restart it. After a judge restart it counts from the next showing.
"""

from __future__ import annotations

import json
import math
import os
import threading
import time
from collections import OrderedDict, deque
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from enum import StrEnum
from pathlib import Path
from typing import Any

from localpbo_core.space import ParameterSpace
from localpbo_msgs_py import (
    CandidateMsg,
    DuelOutcome,
    DuelRequest,
    EpisodeResult,
    EpisodeStatus,
    Incumbent,
    OutcomeKind,
    RunConfig,
    Status,
)
from localpbo_ros.driver import problem_of, settings_of, space_of

MAX_BODY_BYTES = 1024
"""Largest answer body accepted (an answer is ~80 bytes)."""

REPEAT_AFTER_S = 1.0
"""A journaled answer goes out again for a repeated request at most this often."""

HISTORY_SHOWN = 200
"""Answers listed on the page (newest first); the journal keeps all."""

MAX_WORKERS = 1000
"""Evaluators whose busy candidate is tracked at most (from their status heartbeats)."""

ANSWER_KEYS = ("duel_id", "first_id", "second_id", "choice")

JOURNAL_NAME = "answers.jsonl"
SECRET_NAME = "secret"
CONFIG_NAME = "run_config.json"


class Choice(StrEnum):
    """What the person answered."""

    A = "a"
    """The first candidate (A) was better."""
    B = "b"
    """The second candidate (B) was better."""
    TIE = "tie"
    """Can't tell (an indifferent outcome)."""
    SKIP = "skip"
    """Ask again later (nothing is published)."""


@dataclass(frozen=True)
class Reply:
    """The web server's answer to a request: HTTP status and JSON body.

    Refusals carry ``field``, ``reason`` (an identifier, counted as ``dropped_http_<reason>``)
    and ``detail`` in the body.
    """

    status: int
    body: Mapping[str, Any]

    @classmethod
    def refuse(cls, status: int, field: str, reason: str, detail: str) -> Reply:
        """A refusal."""
        return cls(status, {"ok": False, "field": field, "reason": reason, "detail": detail})

    @property
    def reason(self) -> str:
        """The refusal's reason ("" when accepted)."""
        return str(self.body.get("reason", "")) if self.status >= 400 else ""


def tie_threshold_of(config: RunConfig) -> float:
    """The run's ``tie_threshold`` (> 0: the optimizer takes "can't tell")."""
    return float(settings_of(config).tie_threshold)


def parameter_labels(config: RunConfig) -> tuple[tuple[str, ...], tuple[str, ...]]:
    """Names and units of θ's coordinates: a space's own parameters, a MuJoCo task's
    ``W[joint, observation]`` weights, else ``x0, x1, ...``."""
    space = space_of(config)
    if space is not None:
        return space.names, tuple(p.unit for p in space.parameters)
    try:
        problem = problem_of(config)
    except Exception:  # a task this host cannot build still gets numbered parameters
        problem = None
    names_of = getattr(problem, "parameter_names", None)
    if callable(names_of):
        names = tuple(str(n) for n in names_of())
        if len(names) == config.dim:
            return names, ("",) * config.dim
    return tuple(f"x{i}" for i in range(config.dim)), ("",) * config.dim


class Journal:
    """The answers of one run, one JSON line each (``DuelOutcome`` fields), durable.

    Args:
        folder: the run's folder (created, mode 0700).
    """

    def __init__(self, folder: str | os.PathLike[str]) -> None:
        self.folder = Path(folder)
        self.folder.mkdir(parents=True, exist_ok=True, mode=0o700)
        self.path = self.folder / JOURNAL_NAME

    def bind(self, config: RunConfig) -> None:
        """Tie the folder to ``config`` (a resumed run has the same config); refuse a folder
        that holds the answers of another run with the same run id, which would otherwise
        answer the new run's duels.

        Raises:
            ValueError: the folder belongs to another run config.
        """
        path = self.folder / CONFIG_NAME
        text = config.to_json()
        if path.exists():
            if path.read_text(encoding="utf-8") != text:
                raise ValueError(
                    f"{self.folder} holds the answers of another run with id {config.run_id!r}; "
                    "use another run id or state_dir"
                )
            return
        fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
        try:
            os.write(fd, text.encode())
            os.fsync(fd)
        finally:
            os.close(fd)

    def load(self, run_id: str) -> tuple[list[DuelOutcome], int]:
        """The journaled answers of ``run_id`` in order, and the number of unreadable lines
        (a line cut off by a crash, or edited by hand); those are skipped."""
        if not self.path.exists():
            return [], 0
        out: list[DuelOutcome] = []
        bad = 0
        for line in self.path.read_text(encoding="utf-8", errors="replace").splitlines():
            if not line.strip():
                continue
            try:
                obj = json.loads(line)
                out.append(
                    DuelOutcome(
                        run_id,
                        obj["duel_id"],
                        obj["first_id"],
                        obj["second_id"],
                        OutcomeKind(obj["kind"]),
                        obj.get("winner_id"),
                        obj.get("loser_id"),
                        answer_seconds=obj.get("answer_seconds"),
                    )
                )
            except (ValueError, KeyError, TypeError):
                bad += 1
        return out, bad

    def append(self, outcome: DuelOutcome) -> None:
        """Append one answer and force it to disk (raises OSError when that fails)."""
        obj = {
            "duel_id": outcome.duel_id,
            "first_id": outcome.first_id,
            "second_id": outcome.second_id,
            "kind": outcome.kind.value,
            "winner_id": outcome.winner_id,
            "loser_id": outcome.loser_id,
            "answer_seconds": outcome.answer_seconds,
            "wall_time": time.time(),
        }
        line = (json.dumps(obj, allow_nan=False) + "\n").encode()
        created = not self.path.exists()
        fd = os.open(self.path, os.O_WRONLY | os.O_APPEND | os.O_CREAT, 0o600)
        try:
            if os.write(fd, line) != len(line):
                raise OSError(f"short write to {self.path}")
            os.fsync(fd)
        finally:
            os.close(fd)
        if created:  # the new file's directory entry is durable too
            dir_fd = os.open(self.folder, os.O_RDONLY)
            try:
                os.fsync(dir_fd)
            finally:
                os.close(dir_fd)

    def secret(self, make: Callable[[], str]) -> str:
        """The run's URL secret: kept in the folder (mode 0600) so a restarted judge serves
        the same path; made with ``make`` the first time."""
        path = self.folder / SECRET_NAME
        try:
            text = path.read_text(encoding="ascii").strip()
            if len(text) >= 16 and text.replace("-", "").replace("_", "").isalnum():
                return text
        except (OSError, UnicodeDecodeError):
            pass
        text = make()
        fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
        try:
            os.write(fd, text.encode("ascii"))
        finally:
            os.close(fd)
        return text


@dataclass
class _Open:
    """An open duel: its request, when it was first shown ready, how often it was skipped."""

    request: DuelRequest
    shown_at: float | None = None
    skips: int = 0


class JudgeCore:
    """What the judge knows about its run, and the page's answers (see module docstring).

    Args:
        publish: sends an outcome on ``/localpbo/duel_outcome``.
        drop: counts and logs a refused message or request (``reason``, ``detail``).
        max_pending: open duels kept at most (more are dropped as ``buffer_full``).
        clock: monotonic seconds (tests pass their own).
    """

    def __init__(
        self,
        publish: Callable[[DuelOutcome], None],
        drop: Callable[[str, str], None],
        *,
        max_pending: int = 1000,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.lock = threading.RLock()
        self._publish = publish
        self._drop = drop
        self._clock = clock
        self.max_pending = max_pending
        self.config: RunConfig | None = None
        self.secret = ""
        self.journal: Journal | None = None
        self.names: tuple[str, ...] = ()
        self.units: tuple[str, ...] = ()
        self.ties = False
        self.simulated = False
        self.candidates: OrderedDict[int, CandidateMsg] = OrderedDict()
        self.results: dict[int, EpisodeResult] = {}
        self.busy: dict[str, int] = {}
        self.open: OrderedDict[int, _Open] = OrderedDict()
        self.answered: dict[int, DuelOutcome] = {}
        self._sent_at: dict[int, float] = {}
        self.history: deque[dict[str, Any]] = deque(maxlen=HISTORY_SHOWN)
        self.incumbent: Incumbent | None = None
        self.optimizer_state = ""
        self.optimizer_duels = 0
        self.recommended: int | None = None  # the optimizer's info.recommended
        self.counters: dict[str, int] = {}

    # ------------------------------------------------------------------ run
    def reset(self) -> None:
        """Forget the previous run."""
        with self.lock:
            self.config = None
            self.secret = ""
            self.journal = None
            self.candidates.clear()
            self.results.clear()
            self.busy.clear()
            self.open.clear()
            self.answered.clear()
            self._sent_at.clear()
            self.history.clear()
            self.incumbent = None
            self.optimizer_state = ""
            self.optimizer_duels = 0
            self.recommended = None

    def adopt(self, config: RunConfig, journal: Journal, secret: str, *, simulated: bool) -> int:
        """Serve ``config``: load the journal's answers (returns how many).

        Raises:
            ValueError: the journal belongs to another run config (:meth:`Journal.bind`).
        """
        journal.bind(config)
        loaded, bad = journal.load(config.run_id)
        names, units = parameter_labels(config)
        with self.lock:
            self.config = config
            self.journal = journal
            self.secret = secret
            self.names, self.units = names, units
            self.ties = tie_threshold_of(config) > 0
            self.simulated = simulated
            if bad:
                self._count("journal_unreadable_lines", bad)
            for outcome in loaded:
                if outcome.duel_id not in self.answered:
                    self.answered[outcome.duel_id] = outcome
                    self.history.appendleft(self._entry(outcome))
            return len(self.answered)

    def _count(self, name: str, n: int = 1) -> None:
        self.counters[name] = self.counters.get(name, 0) + n

    @property
    def cap(self) -> int:
        """Candidates and results kept at most (the run's budget plus ``max_pending``)."""
        return (self.config.budget if self.config else 0) + self.max_pending

    # ------------------------------------------------------------------ messages
    def on_candidate(self, cand: CandidateMsg) -> None:
        """A candidate of the run (task units)."""
        with self.lock:
            known = self.candidates.get(cand.candidate_id)
            if known is not None:
                if known.theta != cand.theta:
                    self._drop("conflicting_candidate", f"candidate {cand.candidate_id} changed θ")
                return
            if len(self.candidates) >= self.cap:
                self._drop("buffer_full", f"more than {self.cap} candidates")
                return
            self.candidates[cand.candidate_id] = cand.assigned_to("")

    def on_result(self, res: EpisodeResult) -> list[DuelOutcome]:
        """An episode result; returns the failed outcomes of the open duels it fails (to
        publish; the optimizer's failure policy decides, as with the simulated oracle)."""
        with self.lock:
            for worker, cid in list(self.busy.items()):
                if cid == res.candidate_id:
                    del self.busy[worker]
            known = self.results.get(res.candidate_id)
            if known is not None and known.status is EpisodeStatus.OK:
                if res.status is EpisodeStatus.OK and known.episode_return != res.episode_return:
                    self._drop(
                        "conflicting_result",
                        f"candidate {res.candidate_id}: {res.episode_return} after "
                        f"{known.episode_return}",
                    )
                return []
            if len(self.results) >= self.cap:
                self._drop("buffer_full", f"more than {self.cap} results")
                return []
            if res.status is EpisodeStatus.OK:
                self.results[res.candidate_id] = res
                return []
            failed: list[DuelOutcome] = []
            for duel_id, item in list(self.open.items()):
                req = item.request
                if res.candidate_id in (req.first_id, req.second_id):
                    failed.append(
                        DuelOutcome.failed(
                            req, f"episode of candidate {res.candidate_id} failed: {res.error}"
                        )
                    )
                    del self.open[duel_id]
                    self._count("duels_failed")
            return failed

    def on_request(self, req: DuelRequest) -> DuelOutcome | None:
        """A duel request; returns the stored outcome to publish again when it is answered."""
        with self.lock:
            done = self.answered.get(req.duel_id)
            if done is not None:
                if (done.first_id, done.second_id) != (req.first_id, req.second_id):
                    self._drop("conflicting_request", f"duel {req.duel_id} changed its candidates")
                    return None
                now = self._clock()
                if now - self._sent_at.get(req.duel_id, -math.inf) < REPEAT_AFTER_S:
                    self._count("requests_while_answer_in_flight")
                    return None
                self._sent_at[req.duel_id] = now
                self._count("outcomes_repeated")
                return done
            item = self.open.get(req.duel_id)
            if item is not None:
                if item.request != req:
                    self._drop("conflicting_request", f"duel {req.duel_id} changed its candidates")
                return None
            if len(self.open) >= self.max_pending:
                self._drop("buffer_full", f"more than {self.max_pending} duels open")
                return None
            # a failed result is forgotten when its duel is asked again (retry: a fresh one)
            for cid in (req.first_id, req.second_id):
                known = self.results.get(cid)
                if known is not None and known.status is EpisodeStatus.FAILED:
                    del self.results[cid]
            self.open[req.duel_id] = _Open(req)
            return None

    def on_incumbent(self, inc: Incumbent) -> None:
        """The optimizer's current incumbent."""
        with self.lock:
            self.incumbent = inc

    def on_status(self, status: Status) -> None:
        """A status report of the run: the optimizer's progress, a worker's busy candidate."""
        with self.lock:
            if status.node == "optimizer_node" or "duels_done" in status.counters:
                self.optimizer_state = status.state
                self.optimizer_duels = status.counters.get("duels_done", self.optimizer_duels)
                rec = status.info.get("recommended", "")
                if rec.isdigit() and len(rec) < 20:
                    self.recommended = int(rec)
            busy = status.info.get("busy")
            worker = status.info.get("worker")
            if worker is not None and busy is not None:
                if busy.isdigit() and len(busy) < 20 and len(self.busy) < MAX_WORKERS:
                    self.busy[worker] = int(busy)
                else:
                    self.busy.pop(worker, None)

    def episode_return(self, candidate_id: int) -> float | None:
        """The episode return received for a candidate (None if unknown or failed)."""
        with self.lock:
            res = self.results.get(candidate_id)
            return None if res is None else res.episode_return

    # ------------------------------------------------------------------ the page
    def _ready(self, req: DuelRequest) -> bool:
        return all(
            (r := self.results.get(cid)) is not None and r.status is EpisodeStatus.OK
            for cid in (req.first_id, req.second_id)
        )

    def current(self) -> _Open | None:
        """The duel to show: the first ready one in queue order, else the first open one."""
        with self.lock:
            items = list(self.open.values())
            return next((i for i in items if self._ready(i.request)), items[0] if items else None)

    def _side(self, cid: int) -> dict[str, Any]:
        cand = self.candidates.get(cid)
        res = self.results.get(cid)
        if res is not None and res.status is EpisodeStatus.OK:
            state = "done"
        elif cid in self.busy.values():
            state = "evaluating"
        elif cand is not None:
            state = "queued"
        else:
            state = "unknown"
        return {
            "id": cid,
            "theta": None if cand is None else list(cand.theta),
            "result": state,
        }

    def view(self) -> dict[str, Any]:
        """Everything the page shows (``GET api/state``); the current duel counts as shown
        from the first view in which it is ready."""
        with self.lock:
            config = self.config
            if config is None:
                return {"run": None}
            item = self.current()
            duel: dict[str, Any] | None = None
            if item is not None:
                req = item.request
                ready = self._ready(req)
                if ready and item.shown_at is None:
                    item.shown_at = self._clock()
                a, b = self._side(req.first_id), self._side(req.second_id)
                evaluating = None
                if not ready:
                    # the side being evaluated: a worker's busy report, else the first side
                    # (A, then B) still without a result whose candidate went out
                    pending = [(n, s) for n, s in (("A", a), ("B", b)) if s["result"] != "done"]
                    busy = [n for n, s in pending if s["result"] == "evaluating"]
                    sent = [n for n, s in pending if s["result"] == "queued"]
                    evaluating = (busy or sent or [None])[0]
                duel = {
                    "duel_id": req.duel_id,
                    "a": a,
                    "b": b,
                    "ready": ready,
                    "evaluating": evaluating,
                    "skips": item.skips,
                    "others_open": len(self.open) - 1,
                }
            inc = self.incumbent
            return {
                "run": {
                    "run_id": config.run_id,
                    "task": config.task,
                    "algorithm": config.algorithm,
                    "budget": config.budget,
                    "seed": config.seed,
                    "ties": self.ties,
                    "simulated": self.simulated,
                    "names": list(self.names),
                    "units": list(self.units),
                },
                "progress": {
                    "answered": len(self.answered),
                    "open": len(self.open),
                    "evaluations": (max(self.candidates) + 1) if self.candidates else 0,
                    "budget": config.budget,
                    "optimizer_duels": self.optimizer_duels,
                    "optimizer_state": self.optimizer_state,
                },
                "finished": self.optimizer_state in ("done", "failed"),
                "duel": duel,
                "incumbent": None
                if inc is None
                else {"id": inc.candidate_id, "theta": list(inc.theta), "duels": inc.n_duels},
                "recommended": self._recommended(),
                "history": list(self.history),
            }

    def _recommended(self) -> dict[str, Any] | None:
        """The optimizer's current recommendation (id and θ when the candidate is known)."""
        if self.recommended is None:
            return None
        cand = self.candidates.get(self.recommended)
        return {"id": self.recommended, "theta": None if cand is None else list(cand.theta)}

    def answer(self, body: bytes) -> Reply:
        """Handle the body of ``POST api/answer`` (see module docstring)."""
        with self.lock:
            reply, outcome = self._answer(body)
            if reply.status >= 400:
                self._drop(f"http_{reply.reason}", str(reply.body.get("detail", "")))
        if outcome is not None:  # journaled and marked answered: published outside the lock
            self._publish(outcome)
        return reply

    def _answer(self, body: bytes) -> tuple[Reply, DuelOutcome | None]:
        """The reply, and the recorded outcome to publish (None unless recorded)."""
        reply = self._check(body)
        if not isinstance(reply, tuple):
            return reply, None
        item, choice = reply
        if choice is Choice.SKIP:
            self.open.move_to_end(item.request.duel_id)
            item.skips += 1
            self._count("skips")
            alone = len(self.open) == 1
            return Reply(200, {"ok": True, "skipped": item.request.duel_id, "alone": alone}), None
        req = item.request
        seconds = None
        if item.shown_at is not None:
            seconds = max(self._clock() - item.shown_at, 0.0)
        if choice is Choice.TIE:
            outcome = DuelOutcome.indifferent(req, answer_seconds=seconds)
        else:
            winner = req.first_id if choice is Choice.A else req.second_id
            outcome = DuelOutcome.decisive(req, winner, answer_seconds=seconds)
        assert self.journal is not None
        try:
            self.journal.append(outcome)
        except OSError as exc:
            return Reply.refuse(500, "journal", "journal_failed", f"not recorded: {exc}"), None
        self.answered[req.duel_id] = outcome
        del self.open[req.duel_id]
        self._count("answers")
        self.history.appendleft(self._entry(outcome))
        self._sent_at[req.duel_id] = self._clock()
        return Reply(200, {"ok": True, "recorded": req.duel_id, "answer": _said(outcome)}), outcome

    def _check(self, body: bytes) -> Reply | tuple[_Open, Choice]:
        """The open duel and the choice an answer names, or the refusal."""
        if self.config is None or self.journal is None:
            return Reply.refuse(409, "run", "no_run", "no run config received yet")
        if len(body) > MAX_BODY_BYTES:
            return Reply.refuse(
                400, "body", "too_large", f"{len(body)} bytes; at most {MAX_BODY_BYTES}"
            )
        try:
            obj = json.loads(body.decode("utf-8"), parse_constant=_no_constant)
        except (UnicodeDecodeError, ValueError) as exc:
            return Reply.refuse(400, "body", "bad_json", f"not JSON: {str(exc)[:200]}")
        if not isinstance(obj, dict):
            return Reply.refuse(400, "body", "bad_json", "must be a JSON object")
        for key in ANSWER_KEYS:
            if key not in obj:
                return Reply.refuse(400, key, "missing", f"{key} is required")
        for key in obj:
            if key not in ANSWER_KEYS:
                return Reply.refuse(400, str(key)[:40], "unexpected", "unknown field")
        ids: dict[str, int] = {}
        for key in ("duel_id", "first_id", "second_id"):
            value = obj[key]
            if isinstance(value, bool) or not isinstance(value, int) or not 0 <= value < 2**63:
                return Reply.refuse(400, key, "wrong_type", "must be an integer id >= 0")
            ids[key] = value
        choice_text = obj["choice"]
        if not isinstance(choice_text, str) or choice_text not in {c.value for c in Choice}:
            allowed = ", ".join(c.value for c in Choice)
            return Reply.refuse(400, "choice", "unknown_choice", f"must be one of {allowed}")
        choice = Choice(choice_text)
        duel_id = ids["duel_id"]
        done = self.answered.get(duel_id)
        item = self.open.get(duel_id)
        request = done if done is not None else (None if item is None else item.request)
        if request is None:
            return Reply.refuse(400, "duel_id", "unknown_duel", f"duel {duel_id} is not open")
        if (request.first_id, request.second_id) != (ids["first_id"], ids["second_id"]):
            return Reply.refuse(
                400,
                "first_id",
                "wrong_candidates",
                f"duel {duel_id} compares {request.first_id} (A) and {request.second_id} (B)",
            )
        if done is not None:
            return Reply.refuse(
                409,
                "duel_id",
                "already_answered",
                f"duel {duel_id} was already answered: {_said(done)}",
            )
        assert item is not None
        if choice is Choice.TIE and not self.ties:
            return Reply.refuse(
                400, "choice", "ties_disabled", "this run does not take can't-tell answers"
            )
        if choice is not Choice.SKIP and not self._ready(item.request):
            return Reply.refuse(
                409, "duel_id", "not_ready", f"duel {duel_id} is waiting for its episode results"
            )
        return item, choice

    @staticmethod
    def _entry(outcome: DuelOutcome) -> dict[str, Any]:
        return {
            "duel_id": outcome.duel_id,
            "a": outcome.first_id,
            "b": outcome.second_id,
            "answer": _said(outcome),
            "seconds": outcome.answer_seconds,
        }


def _said(outcome: DuelOutcome) -> str:
    """The answer in the page's words."""
    if outcome.kind is OutcomeKind.INDIFFERENT:
        return "can't tell"
    return "A better" if outcome.winner_id == outcome.first_id else "B better"


def _no_constant(name: str) -> float:
    raise ValueError(f"JSON constant {name} is not allowed")


def is_simulated(problem: object) -> bool:
    """The task can replay an episode (a MuJoCo linear-policy task)."""
    return callable(getattr(problem, "record_native", None)) and not isinstance(
        problem, ParameterSpace
    )
