"""Mid-run checkpoints: a run's state at a step boundary, so that a run longer than one batch
job continues where it stopped and ends with the trace one uninterrupted run gives, bit for bit.

A run of the in-process loop (:func:`localpbo_core.loop.run_session`) is a
:class:`~localpbo_core.session.Session` asked and answered step by step. Between two steps
its whole state is the session (the optimizer with its random generators and caches, the duel
bookkeeping) and the loop's trace so far (candidates, values, answers, evaluation records).
:class:`CheckpointedRun` drives that loop and, at the first step boundary after every
``every`` seconds of the run, writes the state to one file. Started again on the file, it
restores the session and hands the loop the trace to continue (the loop sums ``best_seen``
and ``cumulative`` on from the stored records, the same additions in the same order), so the
run ends with the uninterrupted run's trace (``tests/test_checkpoints.py`` checks every
algorithm, killed at random steps and resumed in fresh processes).

The file (``*.ckpt.gz``) is gzip of one JSON header line then the pickled state:

* header: ``schema`` (``localpbo/checkpoint/v1``), ``settings`` (the run's settings document),
  ``code`` (the run sources' and the algorithm's digests, :func:`code_digests`),
  ``evaluations`` (done so far), ``budget``, ``run_seconds`` and ``cpu_seconds`` (so far, all
  segments), and ``segments`` (one per process that ran part of the run: the evaluations it
  ran, its seconds and its ``platform`` block, :func:`localpbo_core.provenance.platform_block`).
* state: :class:`RunState`, pickled by ``cloudpickle`` (glis's GLISp object holds lambdas,
  which the standard pickle refuses); the problem is left out and built again from the
  settings.

A checkpoint continues only a run of the same settings made by code with the same digests
(:func:`read_checkpoint` says why not otherwise, and the run starts from the beginning).
Unpickling runs code named in the file: load only checkpoints your own sweeps wrote, as you
would run only code you trust. Checkpoints made on another platform continue (the run stays a
run of its settings), but its trace may then differ from a run made on either machine alone,
as between any two machines; the run's ``checkpoints`` block lists the segments' platforms.
"""

from __future__ import annotations

import copy
import gzip
import io
import json
import os
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from localpbo_core.loop import RunTrace, run_session
from localpbo_core.session import Session, build_optimizer, build_problem
from localpbo_core.settings import RunSettings, SettingError

SCHEMA = "localpbo/checkpoint/v1"
CHECKPOINT_SUFFIX = ".ckpt.gz"
MAX_HEADER_BYTES = 1 << 20
"""A header line longer than this is refused unread (the file is not a checkpoint)."""


def code_digests(algorithm: str) -> dict[str, str]:
    """The digests a checkpoint must share with today's code to continue: the run sources'
    and ``algorithm``'s (:func:`localpbo_core.provenance.code_block`, without the commit)."""
    from localpbo_core.provenance import code_block

    block = code_block(algorithm)
    return {"digest": str(block["digest"]), "algorithm_digest": str(block["algorithm_digest"])}


@dataclass
class RunState:
    """A run between two steps: its session without the problem (built again from the
    settings) and the loop's trace so far."""

    session: Session
    trace: RunTrace


@dataclass
class Segment:
    """The part of a run one process computed."""

    first_evaluation: int
    last_evaluation: int
    run_seconds: float
    cpu_seconds: float
    platform: dict[str, Any]

    def document(self) -> dict[str, Any]:
        """The segment as a checkpoint header and a stored run list it."""
        return {
            "evaluations": [self.first_evaluation, self.last_evaluation],
            "run_seconds": self.run_seconds,
            "cpu_seconds": self.cpu_seconds,
            "platform": self.platform,
        }


@dataclass
class Checkpoint:
    """A checkpoint file's header and state (module docstring)."""

    header: dict[str, Any]
    state: RunState


@dataclass
class RunResult:
    """A finished run: its trace, seconds over all segments and the segments (more than one
    if it continued a checkpoint)."""

    trace: RunTrace
    run_seconds: float
    cpu_seconds: float
    segments: list[dict[str, Any]] = field(default_factory=list)


class CheckpointError(Exception):
    """A checkpoint that cannot continue this run; ``reason`` says why."""

    def __init__(self, path: Path, reason: str) -> None:
        super().__init__(f"{path}: {reason}")
        self.path = path
        self.reason = reason


def _settings_document(settings: RunSettings) -> dict[str, Any]:
    from localpbo_core.run_documents import settings_document

    return json.loads(json.dumps(settings_document(settings), default=str))


def read_header(path: Path) -> dict[str, Any]:
    """The JSON header of the checkpoint at ``path`` (the state is not unpickled).

    Raises:
        CheckpointError: unreadable, or not a checkpoint.
    """
    try:
        with gzip.open(path, "rb") as fh:
            line = fh.readline(MAX_HEADER_BYTES + 1)
    except (OSError, EOFError) as exc:
        raise CheckpointError(path, f"unreadable: {exc}") from None
    try:
        header = json.loads(line)
    except ValueError:
        header = None
    if not isinstance(header, dict) or header.get("schema") != SCHEMA:
        raise CheckpointError(path, f"not a {SCHEMA} file")
    return header


def read_checkpoint(path: Path, settings: RunSettings) -> Checkpoint:
    """The checkpoint at ``path`` if it continues a run of ``settings`` with today's code,
    its session with the problem built again.

    Raises:
        CheckpointError: unreadable, other settings, other code (``reason`` names which).
    """
    import cloudpickle

    header = read_header(path)
    if header.get("settings") != _settings_document(settings):
        raise CheckpointError(path, "holds a run of other settings")
    today = code_digests(settings.algorithm)
    if header.get("code") != today:
        raise CheckpointError(
            path, f"made by other code (digests {header.get('code')}, today's {today})"
        )
    # The problem is built again; a fresh optimizer, built and dropped, imports and sets up
    # every module the algorithm needs (e.g. glis's import alias) as a fresh run does.
    problem = build_problem(settings)
    build_optimizer(settings, problem.dim)
    try:
        with gzip.open(path, "rb") as fh:
            fh.readline(MAX_HEADER_BYTES + 1)
            state = cloudpickle.load(fh)
    except Exception as exc:  # a truncated or foreign pickle: the run starts again
        raise CheckpointError(path, f"state unreadable: {type(exc).__name__}: {exc}") from None
    if not isinstance(state, RunState) or len(state.trace.records) != header.get("evaluations"):
        raise CheckpointError(path, "state does not match its header")
    state.session.problem = problem
    return Checkpoint(header, state)


def write_checkpoint(path: Path, header: dict[str, Any], state: RunState) -> None:
    """Write ``header`` and ``state`` to ``path`` atomically (temporary file, then rename)."""
    import cloudpickle

    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    buffer = io.BytesIO()
    buffer.write(json.dumps(header).encode() + b"\n")
    cloudpickle.dump(state, buffer, protocol=5)
    with (
        open(tmp, "wb") as raw,
        gzip.GzipFile(fileobj=raw, mode="wb", mtime=0, compresslevel=1) as fh,
    ):
        fh.write(buffer.getvalue())
    os.replace(tmp, path)


class CheckpointedRun:
    """One run of ``settings`` that writes its state to ``path`` at the first step boundary
    after every ``every`` seconds, and continues from ``path`` if a checkpoint of the same
    run and code is there (module docstring).

    Args:
        settings: the run.
        path: the checkpoint file (None: no checkpoints, the plain loop).
        every: seconds of the run between checkpoints (> 0).
        on_discarded: called with the error when a checkpoint at ``path`` cannot continue
            the run (the run then starts from the beginning and overwrites it).
    """

    def __init__(
        self,
        settings: RunSettings,
        path: Path | None,
        every: float,
        on_discarded: Callable[[CheckpointError], None] | None = None,
    ) -> None:
        if not every > 0:
            raise SettingError("--checkpoint-every", f"must be > 0 seconds, got {every!r}")
        self.settings = settings
        self.path = path
        self.every = float(every)
        self.on_discarded = on_discarded
        self.written = 0  # checkpoints written by this process
        self.resumed_at: int | None = None  # evaluations of the checkpoint it continued

    def _resume(self) -> Checkpoint | None:
        if self.path is None or not self.path.exists():
            return None
        try:
            return read_checkpoint(self.path, self.settings)
        except CheckpointError as exc:
            if self.on_discarded is not None:
                self.on_discarded(exc)
            return None

    def run(self) -> RunResult:
        """Run to the budget (from the checkpoint, if one continues it)."""
        from localpbo_core.provenance import platform_block
        from localpbo_core.threads import use_fast_threads

        wall0, cpu0 = time.perf_counter(), time.process_time()
        resumed = self._resume()
        segments: list[dict[str, Any]] = []
        so_far = (0.0, 0.0)  # run and CPU seconds of the earlier segments
        if resumed is None:
            session = Session(self.settings)
            trace = RunTrace()
        else:
            use_fast_threads()
            session, trace = resumed.state.session, resumed.state.trace
            segments = list(resumed.header.get("segments") or [])
            so_far = (float(resumed.header["run_seconds"]), float(resumed.header["cpu_seconds"]))
            self.resumed_at = len(trace.records)
        first = len(trace.records)
        platform = platform_block()
        last = [time.perf_counter()]

        def segment(done: int) -> dict[str, Any]:
            return Segment(
                first + 1,
                done,
                time.perf_counter() - wall0,
                time.process_time() - cpu0,
                platform,
            ).document()

        def on_step(now: RunTrace) -> None:
            if self.path is None or session.done or time.perf_counter() - last[0] < self.every:
                return
            done = len(now.records)
            part = segment(done)
            header = {
                "schema": SCHEMA,
                "settings": _settings_document(self.settings),
                "code": code_digests(self.settings.algorithm),
                "evaluations": done,
                "budget": session.budget,
                "run_seconds": so_far[0] + part["run_seconds"],
                "cpu_seconds": so_far[1] + part["cpu_seconds"],
                "segments": [*segments, part],
            }
            kept = copy.copy(session)
            kept.problem = None  # type: ignore[assignment]  # built again from the settings
            write_checkpoint(self.path, header, RunState(kept, now))
            self.written += 1
            last[0] = time.perf_counter()

        trace = run_session(session, trace=trace, on_step=on_step)
        part = segment(len(trace.records))
        if resumed is not None:
            segments.append(part)
        return RunResult(
            trace=trace,
            run_seconds=so_far[0] + part["run_seconds"],
            cpu_seconds=so_far[1] + part["cpu_seconds"],
            segments=segments,
        )
