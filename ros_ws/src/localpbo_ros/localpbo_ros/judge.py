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
(ask again later: the duel moves to the back of the queue), and optionally ``note`` (the
person's words, at most ``MAX_NOTE`` characters), ``judge`` (the person's name, at most
``MAX_NAME``; default the node's ``name`` parameter), ``visible_seconds`` and ``hidden`` (see
below). The first answer to a duel wins; a later one gets 409 with the recorded answer.
Malformed answers (duplicate keys included) get 400 naming the field and the reason; each
refusal is counted (``dropped_http_<reason>``) by the node. Notes, names and the visibility
flag are journaled with the answer; the bag carries ``answer_seconds``.

**Answer time** (``answer_seconds``): the time the page was *visible* while the duel was
ready to answer, as the page measures it (Page Visibility API: a hidden tab or a minimised
window does not count), capped by the time since the judge first showed the duel ready on
this host's monotonic clock; ``hidden`` (journaled) says the page was hidden meanwhile. A page
that sends no ``visible_seconds`` gets the judge's own measure; a skip does not restart it.
After a judge restart it counts from the next showing.

**Undo** (:meth:`JudgeCore.undo`, ``POST api/undo`` with ``{"duel_id"}``): takes back the
latest recorded answer. The judge journals an ``undo`` line first, then publishes a
``retracted`` outcome for that duel; the optimizer rolls back and asks the duel again (a
request with the same id), and the judge then opens it again and drops the open duels with a
higher id (the optimizer withdrew them). If the optimizer refuses (its status counter
``retraction_refused`` grows) the answer stands again (a ``restore`` line) and the page says
so. One undo is in flight at a time.

**Push**: every change bumps :attr:`JudgeCore.version` and wakes the waiters of
:attr:`JudgeCore.changed`, so the web server streams the page's state the moment it changes.
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

MAX_BODY_BYTES = 8192
"""Largest answer body accepted (an answer is ~80 bytes; a note at most ~4 KiB)."""

MAX_NOTE = 1000
"""Characters of a note at most."""

MAX_NAME = 80
"""Characters of a judge's name at most."""

REPEAT_AFTER_S = 1.0
"""A journaled answer goes out again for a repeated request at most this often."""

HISTORY_SHOWN = 200
"""Answers listed on the page (newest first); the journal keeps all."""

MAX_WORKERS = 1000
"""Evaluators whose busy candidate is tracked at most (from their status heartbeats)."""

ANSWER_KEYS = ("duel_id", "first_id", "second_id", "choice")
OPTIONAL_KEYS = ("note", "judge", "visible_seconds", "hidden")

RETRACTED: OutcomeKind | None = getattr(OutcomeKind, "RETRACTED", None)
"""The outcome kind that takes an answer back (None: the protocol has none)."""

JOURNAL_NAME = "answers.jsonl"
SECRET_NAME = "secret"
PORT_NAME = "port"
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


@dataclass(frozen=True)
class Entry:
    """One journal line: an answer (``outcome`` and what the page sent with it), or an
    ``undo``/``restore`` of the answer to ``duel_id``."""

    duel_id: int
    outcome: DuelOutcome | None = None
    action: str = "answer"
    note: str = ""
    judge: str = ""
    hidden: bool = False


class Journal:
    """The answers of one run, one JSON line each (``DuelOutcome`` fields, plus ``note``,
    ``judge``, ``hidden``), and ``{"undo": id}``/``{"restore": id}`` lines; durable.

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

    def entries(self, run_id: str) -> tuple[list[Entry], int]:
        """The journal's lines of ``run_id`` in order, and the number of unreadable lines
        (a line cut off by a crash, or edited by hand); those are skipped."""
        if not self.path.exists():
            return [], 0
        out: list[Entry] = []
        bad = 0
        for line in self.path.read_text(encoding="utf-8", errors="replace").splitlines():
            if not line.strip():
                continue
            try:
                obj = json.loads(line)
                for action in ("undo", "restore"):
                    if action in obj:
                        duel = obj[action]
                        if isinstance(duel, bool) or not isinstance(duel, int):
                            raise ValueError(f"{action}: not a duel id")
                        out.append(Entry(duel, action=action))
                        break
                else:
                    outcome = DuelOutcome(
                        run_id,
                        obj["duel_id"],
                        obj["first_id"],
                        obj["second_id"],
                        OutcomeKind(obj["kind"]),
                        obj.get("winner_id"),
                        obj.get("loser_id"),
                        answer_seconds=obj.get("answer_seconds"),
                        judge=str(obj.get("judge", "")),
                        note=str(obj.get("note", "")),
                    )
                    out.append(
                        Entry(
                            outcome.duel_id,
                            outcome,
                            note=str(obj.get("note", "")),
                            judge=str(obj.get("judge", "")),
                            hidden=bool(obj.get("hidden", False)),
                        )
                    )
            except (ValueError, KeyError, TypeError):
                bad += 1
        return out, bad

    def load(self, run_id: str) -> tuple[list[DuelOutcome], int]:
        """The answers of ``run_id`` that stand (in order; undone ones left out unless
        restored), and the number of unreadable lines."""
        entries, bad = self.entries(run_id)
        standing: dict[int, DuelOutcome] = {}
        undone: dict[int, DuelOutcome] = {}
        for entry in entries:
            if entry.outcome is not None:
                standing.setdefault(entry.duel_id, entry.outcome)
            elif entry.action == "undo" and entry.duel_id in standing:
                undone[entry.duel_id] = standing.pop(entry.duel_id)
            elif entry.action == "restore" and entry.duel_id in undone:
                standing[entry.duel_id] = undone.pop(entry.duel_id)
        return list(standing.values()), bad

    def append(self, outcome: DuelOutcome, **extra: Any) -> None:
        """Append one answer (with ``extra`` keys: note, judge, hidden, ...) and force it to
        disk (raises OSError when that fails)."""
        obj = {
            "duel_id": outcome.duel_id,
            "first_id": outcome.first_id,
            "second_id": outcome.second_id,
            "kind": outcome.kind.value,
            "winner_id": outcome.winner_id,
            "loser_id": outcome.loser_id,
            "answer_seconds": outcome.answer_seconds,
            "wall_time": time.time(),
            **extra,
        }
        self._write(obj)

    def mark(self, action: str, duel_id: int) -> None:
        """Append an ``undo`` or ``restore`` line for ``duel_id``, durable."""
        self._write({action: duel_id, "wall_time": time.time()})

    def _write(self, obj: Mapping[str, Any]) -> None:
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

    def port(self) -> int | None:
        """The page's port the run was served on last (None the first time)."""
        try:
            text = (self.folder / PORT_NAME).read_text(encoding="ascii").strip()
        except (OSError, UnicodeDecodeError):
            return None
        return int(text) if text.isdigit() and 0 < int(text) < 65536 else None

    def keep_port(self, port: int) -> None:
        """Remember the page's port, so a resumed run serves the open tab on it again."""
        fd = os.open(self.folder / PORT_NAME, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
        try:
            os.write(fd, str(port).encode("ascii"))
        finally:
            os.close(fd)


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
        judge_name: the name recorded with answers that name nobody.
    """

    def __init__(
        self,
        publish: Callable[[DuelOutcome], None],
        drop: Callable[[str, str], None],
        *,
        max_pending: int = 1000,
        clock: Callable[[], float] = time.monotonic,
        judge_name: str = "",
    ) -> None:
        self.lock = threading.RLock()
        self.changed = threading.Condition(self.lock)
        self.version = 0
        self._publish = publish
        self._drop = drop
        self._clock = clock
        self.max_pending = max_pending
        self.judge_name = judge_name[:MAX_NAME]
        self.config: RunConfig | None = None
        self.secret = ""
        self.journal: Journal | None = None
        self.names: tuple[str, ...] = ()
        self.units: tuple[str, ...] = ()
        self.goal = ""
        self.ties = False
        self.simulated = False
        self.candidates: OrderedDict[int, CandidateMsg] = OrderedDict()
        self.results: dict[int, EpisodeResult] = {}
        self.busy: dict[str, int] = {}
        self.open: OrderedDict[int, _Open] = OrderedDict()
        self.answered: dict[int, DuelOutcome] = {}
        self.order: list[int] = []  # answered duels in the order they were answered
        self.retracting: dict[int, DuelOutcome] = {}  # undone, until the optimizer asks again
        self._sent_at: dict[int, float] = {}
        self.history: deque[dict[str, Any]] = deque(maxlen=HISTORY_SHOWN)
        self.notice = ""
        self.incumbent: Incumbent | None = None
        self.optimizer_state = ""
        self.optimizer_duels = 0
        self._refused_seen: int | None = None  # the optimizer's retraction_refused counter
        self.recommended: int | None = None  # the optimizer's info.recommended
        self.counters: dict[str, int] = {}

    def _touch(self) -> None:
        """The page's state changed: wake the streams (call with the lock held)."""
        self.version += 1
        self.changed.notify_all()

    # ------------------------------------------------------------------ run
    def reset(self) -> None:
        """Forget the previous run."""
        with self.lock:
            self.config = None
            self.secret = ""
            self.journal = None
            self.goal = ""
            self.candidates.clear()
            self.results.clear()
            self.busy.clear()
            self.open.clear()
            self.answered.clear()
            self.order.clear()
            self.retracting.clear()
            self._sent_at.clear()
            self.history.clear()
            self.notice = ""
            self.incumbent = None
            self.optimizer_state = ""
            self.optimizer_duels = 0
            self._refused_seen = None
            self.recommended = None
            self._touch()

    def adopt(self, config: RunConfig, journal: Journal, secret: str, *, simulated: bool) -> int:
        """Serve ``config``: load the journal's answers (returns how many stand).

        Raises:
            ValueError: the journal belongs to another run config (:meth:`Journal.bind`).
        """
        journal.bind(config)
        entries, bad = journal.entries(config.run_id)
        names, units = parameter_labels(config)
        goal = goal_of(config)
        with self.lock:
            self.config = config
            self.journal = journal
            self.secret = secret
            self.names, self.units = names, units
            self.goal = goal
            self.ties = tie_threshold_of(config) > 0
            self.simulated = simulated
            if bad:
                self._count("journal_unreadable_lines", bad)
            for entry in entries:
                self._replay(entry)
            self._touch()
            return len(self.answered)

    def _replay(self, entry: Entry) -> None:
        """Apply one journal line (adopt)."""
        duel = entry.duel_id
        if entry.outcome is not None:
            if duel not in self.answered:
                self.retracting.pop(duel, None)
                self._record(entry.outcome, entry.note, entry.judge, entry.hidden)
        elif entry.action == "undo" and duel in self.answered:
            self.retracting[duel] = self.answered.pop(duel)
            self.order.remove(duel)
            self._mark_history(duel, "undone")
        elif entry.action == "restore" and duel in self.retracting:
            self.answered[duel] = self.retracting.pop(duel)
            self.order.append(duel)
            self._mark_history(duel, "")

    def _record(self, outcome: DuelOutcome, note: str, judge: str, hidden: bool) -> None:
        self.answered[outcome.duel_id] = outcome
        self.order.append(outcome.duel_id)
        self.history.appendleft(self._entry(outcome, note, judge, hidden))

    def _mark_history(self, duel_id: int, undone: str) -> None:
        """Mark the newest history entry of ``duel_id`` undone ("undone") or standing ("")."""
        for item in self.history:
            if item["duel_id"] == duel_id:
                item["undone"] = undone
                return

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
            self._touch()

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
            self._touch()
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
        """A duel request; returns the stored outcome to publish again when it is answered
        (or the retraction to publish again, when the optimizer asks past an undone duel)."""
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
            undone = self.retracting.pop(req.duel_id, None)
            if undone is not None:
                if (undone.first_id, undone.second_id) != (req.first_id, req.second_id):
                    self.retracting[req.duel_id] = undone
                    self._drop("conflicting_request", f"duel {req.duel_id} changed its candidates")
                    return None
                # asked again: the optimizer took the answer back and withdrew later duels
                for later in [d for d in self.open if d > req.duel_id]:
                    del self.open[later]
                    self._count("duels_withdrawn")
                self.open[req.duel_id] = _Open(req)
                self.open.move_to_end(req.duel_id, last=False)
                self.notice = f"Duel {req.duel_id} is open again: answer it anew."
                self._touch()
                return None
            if self.retracting and min(self.retracting) < req.duel_id:
                first = min(self.retracting)
                now = self._clock()
                if now - self._sent_at.get(first, -math.inf) >= REPEAT_AFTER_S:
                    self._sent_at[first] = now
                    self._count("retractions_repeated")
                    return self._retraction(self.retracting[first])
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
            self._touch()
            return None

    def on_incumbent(self, inc: Incumbent) -> None:
        """The optimizer's current incumbent."""
        with self.lock:
            if inc != self.incumbent:
                self.incumbent = inc
                self._touch()

    def on_status(self, status: Status) -> None:
        """A status report of the run: the optimizer's progress, a worker's busy candidate,
        a refused retraction."""
        with self.lock:
            before = (
                self.optimizer_state,
                self.optimizer_duels,
                self.recommended,
                dict(self.busy),
            )
            if status.node == "optimizer_node" or "duels_done" in status.counters:
                self.optimizer_state = status.state
                self.optimizer_duels = status.counters.get("duels_done", self.optimizer_duels)
                rec = status.info.get("recommended", "")
                if rec.isdigit() and len(rec) < 20:
                    self.recommended = int(rec)
                refused = status.counters.get("retraction_refused", 0)
                if self._refused_seen is not None and refused > self._refused_seen:
                    self._restore_all()
                self._refused_seen = refused
            busy = status.info.get("busy")
            worker = status.info.get("worker")
            if worker is not None and busy is not None:
                if busy.isdigit() and len(busy) < 20 and len(self.busy) < MAX_WORKERS:
                    self.busy[worker] = int(busy)
                else:
                    self.busy.pop(worker, None)
            after = (self.optimizer_state, self.optimizer_duels, self.recommended, self.busy)
            if after != before:
                self._touch()

    def _restore_all(self) -> None:
        """The optimizer refused the undo: the answers in flight stand again."""
        for duel_id in sorted(self.retracting):
            if self.journal is not None:
                try:
                    self.journal.mark("restore", duel_id)
                except OSError as exc:
                    self._drop("journal_failed", f"restore of duel {duel_id}: {exc}")
            self.answered[duel_id] = self.retracting.pop(duel_id)
            self.order.append(duel_id)
            self._mark_history(duel_id, "")
            self._count("undo_refused")
            self.notice = (
                f"The optimizer refused to take back duel {duel_id} (other answers depend on "
                "it): its answer stands."
            )
        self._touch()

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
        """The duel to show: the first ready one in queue order, else the first open one;
        never one that an undo under way withdraws (:meth:`_withdrawn`)."""
        with self.lock:
            items = [i for i in self.open.values() if not self._withdrawn(i.request.duel_id)]
            return next((i for i in items if self._ready(i.request)), items[0] if items else None)

    def _withdrawn(self, duel_id: int) -> bool:
        """Duel ``duel_id`` was asked after an answer that is being taken back: the optimizer
        withdraws it when it asks the undone duel again (it stays open here until then, and
        again shown if the optimizer refuses the undo)."""
        return bool(self.retracting) and duel_id > min(self.retracting)

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
        """Everything the page shows (``GET api/state``, and each pushed state); the current
        duel counts as shown from the first view in which it is ready."""
        with self.lock:
            config = self.config
            if config is None:
                return {"run": None, "version": self.version}
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
                    evaluating = next(iter(busy + sent), None)
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
            last = self.order[-1] if self.order else None
            undo = None
            if last is not None and not self.retracting and RETRACTED is not None:
                undo = {"duel_id": last, "answer": _said(self.answered[last])}
            return {
                "version": self.version,
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
                    "goal": self.goal,
                    "judge": self.judge_name,
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
                "undo": undo,
                "retracting": sorted(self.retracting),
                "notice": self.notice,
                "incumbent": None
                if inc is None
                else {"id": inc.candidate_id, "theta": list(inc.theta), "duels": inc.n_duels},
                "recommended": self._recommended(),
                "history": [dict(h) for h in self.history],
            }

    def _recommended(self) -> dict[str, Any] | None:
        """The optimizer's current recommendation (id and θ when the candidate is known)."""
        if self.recommended is None:
            return None
        cand = self.candidates.get(self.recommended)
        return {"id": self.recommended, "theta": None if cand is None else list(cand.theta)}

    def answer(self, body: bytes) -> Reply:
        """Handle the body of ``POST api/answer`` (see module docstring)."""
        return self._handle(self._answer, body)

    def _handle(
        self, handler: Callable[[bytes], tuple[Reply, DuelOutcome | None]], body: bytes
    ) -> Reply:
        """``handler``'s reply to ``body``, run under the lock: a refused request is dropped
        and counted, an accepted one wakes the page's streams. The outcome it returns
        (journaled and marked answered, or a retraction) is published outside the lock."""
        with self.lock:
            reply, outcome = handler(body)
            if reply.status >= 400:
                self._drop(f"http_{reply.reason}", str(reply.body.get("detail", "")))
            else:
                self._touch()
        if outcome is not None:
            self._publish(outcome)
        return reply

    def _answer(self, body: bytes) -> tuple[Reply, DuelOutcome | None]:
        """The reply, and the recorded outcome to publish (None unless recorded)."""
        reply = self._check(body)
        if not isinstance(reply, tuple):
            return reply, None
        item, choice, extra = reply
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
        server_seconds = seconds
        visible = extra.get("visible_seconds")
        if visible is not None:
            seconds = visible if seconds is None else min(visible, seconds)
        note = str(extra.get("note", ""))
        judge = str(extra.get("judge", "")) or self.judge_name
        if choice is Choice.TIE:
            outcome = DuelOutcome.indifferent(req, answer_seconds=seconds, judge=judge, note=note)
        else:
            winner = req.first_id if choice is Choice.A else req.second_id
            outcome = DuelOutcome.decisive(
                req, winner, answer_seconds=seconds, judge=judge, note=note
            )
        hidden = bool(extra.get("hidden", False))
        assert self.journal is not None
        try:
            self.journal.append(
                outcome, note=note, judge=judge, hidden=hidden, server_seconds=server_seconds
            )
        except OSError as exc:
            return Reply.refuse(500, "journal", "journal_failed", f"not recorded: {exc}"), None
        del self.open[req.duel_id]
        self._record(outcome, note, judge, hidden)
        self._count("answers")
        self.notice = ""
        self._sent_at[req.duel_id] = self._clock()
        return Reply(200, {"ok": True, "recorded": req.duel_id, "answer": _said(outcome)}), outcome

    def _parse(self, body: bytes) -> Reply | dict[str, Any]:
        """The JSON object of a request body, or the refusal."""
        if self.config is None or self.journal is None:
            return Reply.refuse(409, "run", "no_run", "no run config received yet")
        if len(body) > MAX_BODY_BYTES:
            return Reply.refuse(
                400, "body", "too_large", f"{len(body)} bytes; at most {MAX_BODY_BYTES}"
            )
        try:
            obj = json.loads(
                body.decode("utf-8"), parse_constant=_no_constant, object_pairs_hook=_no_repeats
            )
        except _Repeated as exc:
            return Reply.refuse(400, exc.key[:40], "duplicate_key", "a key appears twice")
        except (UnicodeDecodeError, ValueError) as exc:
            return Reply.refuse(400, "body", "bad_json", f"not JSON: {str(exc)[:200]}")
        if not isinstance(obj, dict):
            return Reply.refuse(400, "body", "bad_json", "must be a JSON object")
        return obj

    def _check(self, body: bytes) -> Reply | tuple[_Open, Choice, dict[str, Any]]:
        """The open duel, the choice and the optional fields an answer names, or the
        refusal."""
        obj = self._parse(body)
        if isinstance(obj, Reply):
            return obj
        for key in ANSWER_KEYS:
            if key not in obj:
                return Reply.refuse(400, key, "missing", f"{key} is required")
        for key in obj:
            if key not in ANSWER_KEYS and key not in OPTIONAL_KEYS:
                return Reply.refuse(400, str(key)[:40], "unexpected", "unknown field")
        extra = _optional(obj)
        if isinstance(extra, Reply):
            return extra
        ids: dict[str, int] = {}
        for key in ("duel_id", "first_id", "second_id"):
            value = obj[key]
            if not _is_id(value):
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
        if self._withdrawn(duel_id):
            first = min(self.retracting)
            return Reply.refuse(
                409,
                "duel_id",
                "withdrawn",
                f"duel {duel_id} was asked after duel {first}, whose answer is being taken "
                f"back: the optimizer withdraws it and asks duel {first} again",
            )
        if choice is Choice.TIE and not self.ties:
            return Reply.refuse(
                400, "choice", "ties_disabled", "this run does not take can't-tell answers"
            )
        if choice is not Choice.SKIP and not self._ready(item.request):
            return Reply.refuse(
                409, "duel_id", "not_ready", f"duel {duel_id} is waiting for its episode results"
            )
        return item, choice, extra

    def undo(self, body: bytes) -> Reply:
        """Handle the body of ``POST api/undo``: ``{"duel_id"}`` must name the latest
        recorded answer (see module docstring)."""
        return self._handle(self._undo, body)

    def _undo(self, body: bytes) -> tuple[Reply, DuelOutcome | None]:
        obj = self._parse(body)
        if isinstance(obj, Reply):
            return obj, None
        for key in obj:
            if key != "duel_id":
                return Reply.refuse(400, str(key)[:40], "unexpected", "unknown field"), None
        duel_id = obj.get("duel_id")
        if not _is_id(duel_id):
            return Reply.refuse(400, "duel_id", "wrong_type", "must be an integer id >= 0"), None
        assert isinstance(duel_id, int)
        if RETRACTED is None:
            detail = "this build's run protocol cannot take an answer back"
            return Reply.refuse(501, "duel_id", "no_retraction", detail), None
        if self.retracting:
            pending = min(self.retracting)
            detail = f"the undo of duel {pending} is still on its way to the optimizer"
            return Reply.refuse(409, "duel_id", "undo_pending", detail), None
        if not self.order or self.order[-1] != duel_id:
            last = self.order[-1] if self.order else None
            detail = f"only the latest answer can be undone (duel {last})"
            return Reply.refuse(409, "duel_id", "not_latest", detail), None
        outcome = self.answered[duel_id]
        assert self.journal is not None
        try:
            self.journal.mark("undo", duel_id)
        except OSError as exc:
            return Reply.refuse(500, "journal", "journal_failed", f"not undone: {exc}"), None
        del self.answered[duel_id]
        self.order.pop()
        self.retracting[duel_id] = outcome
        self._mark_history(duel_id, "undone")
        self._count("undos")
        self._sent_at[duel_id] = self._clock()
        self.notice = f"Undoing duel {duel_id} ({_said(outcome)}): waiting for the optimizer…"
        reply = Reply(200, {"ok": True, "undone": duel_id, "answer": _said(outcome)})
        return reply, self._retraction(outcome)

    @staticmethod
    def _retraction(outcome: DuelOutcome) -> DuelOutcome:
        assert RETRACTED is not None
        return DuelOutcome(
            outcome.run_id, outcome.duel_id, outcome.first_id, outcome.second_id, RETRACTED
        )

    @staticmethod
    def _entry(outcome: DuelOutcome, note: str, judge: str, hidden: bool) -> dict[str, Any]:
        return {
            "duel_id": outcome.duel_id,
            "a": outcome.first_id,
            "b": outcome.second_id,
            "answer": _said(outcome),
            "seconds": outcome.answer_seconds,
            "note": note,
            "judge": judge,
            "hidden": hidden,
            "undone": "",
        }


class _Repeated(ValueError):
    def __init__(self, key: str) -> None:
        super().__init__(f"key {key!r} repeated")
        self.key = key


def _no_repeats(pairs: list[tuple[str, Any]]) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for key, value in pairs:
        if key in out:
            raise _Repeated(key)
        out[key] = value
    return out


def _is_id(value: object) -> bool:
    return isinstance(value, int) and not isinstance(value, bool) and 0 <= value < 2**63


def _optional(obj: Mapping[str, Any]) -> Reply | dict[str, Any]:
    """The optional fields of an answer, checked (``note``, ``judge``, ``visible_seconds``,
    ``hidden``), or the refusal."""
    out: dict[str, Any] = {}
    for key, limit in (("note", MAX_NOTE), ("judge", MAX_NAME)):
        if key in obj:
            value = obj[key]
            if not isinstance(value, str) or len(value) > limit:
                detail = f"must be text of at most {limit} characters"
                return Reply.refuse(400, key, "wrong_type", detail)
            out[key] = value.strip()
    if "visible_seconds" in obj:
        value = obj["visible_seconds"]
        ok = isinstance(value, int | float) and not isinstance(value, bool)
        if not ok or not math.isfinite(value) or value < 0:
            detail = "must be a finite number of seconds >= 0"
            return Reply.refuse(400, "visible_seconds", "wrong_type", detail)
        out["visible_seconds"] = float(value)
    if "hidden" in obj:
        if not isinstance(obj["hidden"], bool):
            return Reply.refuse(400, "hidden", "wrong_type", "must be true or false")
        out["hidden"] = obj["hidden"]
    return out


def goal_of(config: RunConfig) -> str:
    """What "better" means for the run: a space's ``goal``, a task's ``goal`` ("" if none)."""
    space = space_of(config)
    if space is not None:
        return space.goal
    try:
        problem = problem_of(config)
    except Exception:  # a task this host cannot build: no goal to show
        return ""
    return str(getattr(problem, "goal", "") or "")


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
