"""``localpbo sweep SPEC``: every run of an experiment spec as a Ray task, resumable.

* **Execution**: each run (:class:`~localpbo_core.experiments.PlannedRun`) is one Ray task
  (``num_cpus=1``) that builds its :class:`~localpbo_core.session.Session` and drives it
  with :func:`~localpbo_core.loop.run_session`, exactly as ``localpbo bench`` does in-process,
  so the same settings give the same trace (candidates, values, answers, true values) in a
  worker and in-process; only the measured seconds differ. By default an embedded local Ray
  starts with ``num_cpus`` = the machine's cores (``--workers``); ``--address`` submits to an
  existing cluster instead (every node needs this package installed). Ray sets
  ``OMP_NUM_THREADS`` to a task's ``num_cpus`` (1) in its workers, so torch and BLAS run one
  thread per task, which is also the rule of :mod:`localpbo_core.threads`.
  ``--in-process`` runs the plan sequentially without Ray. The embedded Ray runs in a
  private temporary folder under a watchdog process, so that neither its processes nor its
  folder outlive the driver, also when the driver is killed (:mod:`localpbo_core.ray_cleanup`).
* **Storage**: one gzip-compressed JSON document per finished run,
  ``OUT/runs/<run_id>.json.gz`` (``run_id`` = ``<problem>__<algorithm>[__<variant>]__seed<k>``):
  the content of ``localpbo bench``'s ``runs/*.json`` (schema ``localpbo/run/v1``: settings,
  candidates, answers, per-evaluation records) plus ``run`` (spec name, labels, seed,
  within-model flag), ``optimizer_seconds``, ``run_seconds`` and ``cpu_seconds`` (the
  run's wall and process CPU seconds: their ratio is the share of a core the run got, below
  one when other processes kept it waiting), ``code`` (which code made it,
  :mod:`localpbo_core.provenance`), ``platform`` (where: the CPU, torch's kernel level and
  threads, the numerical libraries' versions, :func:`localpbo_core.provenance.platform_block`)
  and ``effective_settings`` (the settings with every
  optimizer option completed by the algorithm's defaults and the budget resolved, so a run
  says what it ran even after a default changes). The driver writes it atomically (a temporary
  file in the same folder, then ``os.replace``), with a fixed gzip time stamp.
* **Resume**: a run whose file exists (and holds the same settings) is finished and skipped;
  a run whose worker died is retried by Ray (``max_retries``); a run that raised is reported
  at the end and not stored, so the next sweep tries it again. ``--max-runs N`` runs only
  the first N unfinished runs; ``--problems``, ``--algorithms``, ``--variants`` (labels) and
  ``--seeds`` select a slice; ``--dry-run`` lists the runs and their state. Ctrl-C or
  SIGTERM stops the runs under way (Ray's workers with them) and exits with 130 after the
  summary; what finished is stored, and the same command continues.
* **Checkpoints** (``--checkpoint-every 10m``, the default; ``--no-checkpoints``): a run
  under way writes its state to ``OUT/checkpoints/<run_id>.ckpt.gz`` at the first step
  boundary after every interval of its own time (:mod:`localpbo_core.checkpoints`), and a
  sweep that claims a run with a checkpoint of the same settings and code continues from it
  to the trace the uninterrupted run gives, bit for bit; so a stopped run loses at most one
  interval and a step, and a run longer than any one batch job finishes over several. The
  stored run's ``run_seconds`` and ``cpu_seconds`` sum every part, and its ``checkpoints``
  block lists the parts (evaluations, seconds, platform). The checkpoint is removed once
  the run is stored; one that cannot continue the run (other settings or code, unreadable)
  is logged and the run starts again. A Ray worker writes the file itself: on a cluster
  ``OUT`` must be a folder every node reaches at the same path.
* **Time limit** (``--time-limit 90m``; e.g. a batch job's wall time): a run is not started
  when the longest run of its group (problem, algorithm, variant) stored in ``OUT`` says it
  would end after the limit (:class:`RunTimes`; a run continued from a checkpoint counts
  the checkpoint's seconds as done), unless checkpoints are on and at least one interval is
  left, so that its progress is kept; a group with no measured run in ``OUT``
  takes the longest of the same run ids in the folders named by ``--times-from DIR``
  (repeatable; e.g. the spec that ran the same problem and algorithm under other settings),
  and with none there either it starts. At the limit the runs still under way stop as on
  SIGTERM (exit 130), so the limit holds either way, and the same command continues (from
  the runs' checkpoints). Ray sweeps keep at most as many runs submitted as the cluster has
  CPUs, submitting the next as one ends, so both rules apply there too.
* **Two sweeps, one folder**: a sweep claims each run before computing it
  (:mod:`localpbo_core.run_claims`: a lock the kernel drops when the sweep ends, however it
  ends) and passes over runs another live sweep holds, listing them as under way there; a
  run another sweep stored meanwhile is skipped. So a second copy of a command never
  computes a run twice, and the same ``--in-process`` command started in two shells splits
  the runs between them (each claims the next free run just before computing it; a Ray
  sweep claims the runs it submits). ``--dry-run`` shows claimed runs as "under way". Every
  write of a run, copies by ``--reuse`` too, happens under its claim, so the claim's holder
  removes the temporary file a writer killed mid-write left behind.
* **Re-run** (``--rerun-changed``): a stored run that today's code is not known to make again
  (its algorithm's sources changed since it was stored and no recorded re-run showed the same
  trace, or no code version is known: "changed since" and "none stored" of
  :func:`localpbo_core.provenance.run_code_state`) is run again. The tables that date runs
  without a code block (``stored_code.json``) and record equivalent code
  (``equivalent_code.json``) are read from ``OUT`` and its parent, where the results folder
  keeps them. The stored file is replaced only when the new run is written (atomically), so
  an interrupted re-run keeps the old run and the same command continues; a re-run is never
  copied by ``--reuse``. The re-run's document gets a ``replaced`` block saying what it
  replaced and how far the two agree (:func:`localpbo_core.provenance.replaced_block`).
* **Reuse** (``--reuse DIR``, repeatable): a run that another sweep already stored in
  ``DIR/runs/`` with the same settings is copied instead of computed; its ``run`` block is
  this spec's, with ``reused_from`` naming the source (``<spec>/<run_id>``), and its
  ``optimizer_seconds`` are those measured for the source. Runs are deterministic in their
  settings, so the copy is the run this sweep would make (e.g. Sobol and GLISp, which take
  no GP hyperparameters, run identically within and out of model). Settings are compared
  with the optimizer options completed by the algorithm's defaults, so an ablation's
  ``qeubo_q1`` (``batch_size: 1`` spelled out) reuses plain ``qeubo`` runs; labels and run
  ids may differ. Settings that differ in any other way are not reused.
"""

from __future__ import annotations

import contextlib
import gzip
import json
import logging
import os
import re
import signal
import socket
import sys
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, NoReturn

from localpbo_core.experiments import ExperimentSpec, PlannedRun
from localpbo_core.provenance import (
    STALE_STATES,
    ProvenanceTables,
    code_block,
    platform_block,
    replaced_block,
    run_code_state,
)
from localpbo_core.run_claims import CLAIMS_DIR, Claim, Holder, holder, try_claim
from localpbo_core.settings import SettingError

RUN_SUFFIX = ".json.gz"
CHECKPOINTS_DIR = "checkpoints"
CHECKPOINT_EVERY_S = 600.0
"""Default seconds of a run between two of its checkpoints (``--checkpoint-every``)."""
_log = logging.getLogger("localpbo.sweep")
MAX_RETRIES = 3
"""Ray retries of a task whose worker process died (not of a run that raised)."""


@dataclass
class SweepResult:
    """What a sweep did: run ids finished now (``rerun``: those of them that replaced a run
    stored by older code), skipped as already stored, failed, left to run (beyond
    ``max_runs``, or unfinished when the sweep was interrupted), and passed over because
    another sweep holds their claim (``elsewhere``: run id to who holds it,
    :mod:`localpbo_core.run_claims`)."""

    finished: list[str] = field(default_factory=list)
    skipped: list[str] = field(default_factory=list)
    failed: dict[str, str] = field(default_factory=dict)
    pending: list[str] = field(default_factory=list)
    interrupted: bool = False
    reused: list[str] = field(default_factory=list)
    rerun: list[str] = field(default_factory=list)
    elsewhere: dict[str, str] = field(default_factory=dict)
    over_time: list[str] = field(default_factory=list)
    time_limit_reached: bool = False
    resumed: dict[str, int] = field(default_factory=dict)
    """Run ids finished now that continued a checkpoint, and its evaluations."""
    kept: dict[str, int] = field(default_factory=dict)
    """Pending run ids with a checkpoint for the next sweep, and its evaluations."""


def run_path(out: Path, plan: PlannedRun) -> Path:
    """``OUT/runs/<run_id>.json.gz``."""
    return out / "runs" / f"{plan.run_id}{RUN_SUFFIX}"


def execute_run(
    plan: PlannedRun, checkpoint: Path | None = None, every: float = CHECKPOINT_EVERY_S
) -> dict[str, Any]:
    """Run ``plan`` in this process and return its stored document (module docstring);
    with ``checkpoint``, continue from that file if it holds a checkpoint of the run, and
    write one there every ``every`` seconds (:mod:`localpbo_core.checkpoints`)."""
    from localpbo_core.checkpoints import CheckpointedRun, CheckpointError
    from localpbo_core.run_documents import trace_document

    def discarded(error: CheckpointError) -> None:
        _log.warning("%s: checkpoint not used, the run starts again: %s", plan.run_id, error)

    done = CheckpointedRun(plan.settings, checkpoint, every, on_discarded=discarded).run()
    trace = done.trace
    doc = trace_document(plan.settings, trace)
    doc["run"] = plan.describe()
    doc["optimizer_seconds"] = sum(r.decision_seconds for r in trace.records)
    doc["run_seconds"] = done.run_seconds
    doc["cpu_seconds"] = done.cpu_seconds
    if done.segments:
        doc["checkpoints"] = {"segments": done.segments}
    doc["code"] = code_block(plan.settings.algorithm)
    doc["platform"] = platform_block()
    effective = effective_settings(doc["settings"])
    if effective is not None:
        effective["budget"] = len(trace.records)
    doc["effective_settings"] = effective
    return doc


def write_run(path: Path, doc: dict[str, Any]) -> None:
    """Write ``doc`` as gzip-JSON atomically (temporary file + rename, fixed time stamp)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    data = (json.dumps(doc, default=str) + "\n").encode()
    with open(tmp, "wb") as raw, gzip.GzipFile(fileobj=raw, mode="wb", mtime=0) as fh:
        fh.write(data)
    os.replace(tmp, path)


def checkpoint_path(out: Path, plan: PlannedRun) -> Path:
    """``OUT/checkpoints/<run_id>.ckpt.gz`` (absolute: a Ray worker writes it)."""
    from localpbo_core.checkpoints import CHECKPOINT_SUFFIX

    return out.resolve() / CHECKPOINTS_DIR / f"{plan.run_id}{CHECKPOINT_SUFFIX}"


def _remove_partial_writes(out: Path, plan: PlannedRun) -> None:
    """Remove the temporary files of ``plan``'s run and checkpoint left by a writer that was
    killed while writing (:func:`write_run`, :func:`localpbo_core.checkpoints.write_checkpoint`).
    Called by the holder of the run's claim: every write of a run happens under its claim, so
    no live writer owns them."""
    for final in (run_path(out, plan), checkpoint_path(out, plan)):
        for tmp in final.parent.glob(f".{final.name}.*.tmp"):
            with contextlib.suppress(FileNotFoundError):
                tmp.unlink()


def read_run(path: Path) -> dict[str, Any]:
    """A stored run document (``.json.gz`` or the plain ``.json`` of ``localpbo bench``)."""
    data = gzip.decompress(path.read_bytes()) if path.name.endswith(".gz") else path.read_bytes()
    return decode_run(data, str(path))


def decode_run(data: bytes, source: str) -> dict[str, Any]:
    """The run document in the JSON bytes ``data`` (``source`` names them in the error).

    Parsed by ``orjson`` (the same values as the standard library's parser, float for float,
    about 2.8 times faster: ``python -m localpbo_core.benchmarks.read_runs``), or by ``json``
    for the documents ``orjson`` refuses (``NaN`` and ``Infinity`` are not JSON)."""
    import orjson

    try:
        doc = orjson.loads(data)
    except orjson.JSONDecodeError:
        doc = json.loads(data)
    if not isinstance(doc, dict) or doc.get("schema") != "localpbo/run/v1":
        raise SettingError("results", f"{source} is not a localpbo/run/v1 document")
    return doc


def stored_state(out: Path, plan: PlannedRun, tables: ProvenanceTables | None = None) -> str:
    """``"finished"`` if ``plan``'s file exists and holds the same settings, ``"stale"`` if
    it does but, with ``tables`` given, was made by code that today's is not known to
    reproduce (module docstring, "Re-run"), else ``"missing"`` (an unreadable file too: it
    runs again). The file is read once.

    Raises:
        SettingError: the file holds a run with other settings (field ``--out``).
    """
    from localpbo_core.run_documents import settings_document

    path = run_path(out, plan)
    if not path.exists():
        return "missing"
    try:
        doc = read_run(path)
    except (OSError, ValueError, EOFError):
        return "missing"
    if doc.get("settings") != settings_document(plan.settings):
        raise SettingError(
            "--out", f"{path} holds run {plan.run_id} with other settings; use another --out"
        )
    if tables is not None and run_code_state(path, doc, tables) in STALE_STATES:
        return "stale"
    return "finished"


def rerun_tables(out: Path) -> ProvenanceTables:
    """The provenance tables ``--rerun-changed`` reads: those in ``out`` and its parent."""
    return ProvenanceTables(dict.fromkeys((out, out.resolve().parent)))


def effective_settings(
    settings: dict[str, Any], known: dict[str, dict[str, object]] | None = None
) -> dict[str, Any] | None:
    """A stored ``settings`` block with its optimizer options completed by the algorithm's
    defaults (:func:`~localpbo_core.optimizers.optimizer_defaults`), in JSON types, so that
    an option spelled out at its default and one left out compare equal. None if the
    algorithm is not registered. ``known``, if given, keeps the defaults looked up by
    algorithm name for the next call (reading a signature costs milliseconds a run)."""
    from localpbo_core.optimizers import optimizer_defaults

    name = str(settings.get("algorithm"))
    if known is not None and name in known:
        defaults = known[name]
    else:
        try:
            defaults = optimizer_defaults(name)
        except SettingError:
            return None
        if known is not None:
            known[name] = defaults
    skip = set(settings)  # e.g. initial_design: a field of the settings, not an option
    options = {k: v for k, v in defaults.items() if k not in skip}
    options.update(settings.get("optimizer_options") or {})
    return {
        **settings,
        "optimizer_options": json.loads(json.dumps(options, default=str)),
    }


_FolderIndex = dict[tuple[str, ...], list[tuple[dict[str, Any], Path]]]
"""Stored runs of one folder by (algorithm, problem, seed): effective settings and file."""


def _run_key(settings: dict[str, Any]) -> tuple[str, ...]:
    return tuple(str(settings.get(k)) for k in ("algorithm", "problem", "seed"))


class ReuseIndex:
    """The runs stored by other sweeps (``--reuse DIR``, module docstring "Reuse"), found by
    their effective settings (:func:`effective_settings`) whatever their run id.

    A folder's files are read once, on the first run not found under its own run id; an
    unreadable file is passed over."""

    def __init__(self, folders: Sequence[Path]) -> None:
        self.folders = list(folders)
        self._index: dict[Path, _FolderIndex] = {}

    def __bool__(self) -> bool:
        return bool(self.folders)

    def _folder_index(self, folder: Path) -> _FolderIndex:
        if folder not in self._index:
            index: _FolderIndex = {}
            for path in sorted((folder / "runs").glob(f"*{RUN_SUFFIX}")):
                try:
                    settings = read_run(path).get("settings")
                except (OSError, ValueError, EOFError):
                    continue
                if not isinstance(settings, dict):
                    continue
                effective = effective_settings(settings)
                if effective is None:
                    continue
                key = _run_key(settings)
                index.setdefault(key, []).append((effective, path))
            self._index[folder] = index
        return self._index[folder]

    def find(self, plan: PlannedRun) -> Path | None:
        """The first stored run (folders in order; within a folder ``plan``'s own run id
        first, then the others by name) whose effective settings are ``plan``'s; None if
        there is none."""
        from localpbo_core.run_documents import settings_document

        wanted_doc = settings_document(plan.settings)
        wanted = effective_settings(wanted_doc)
        if wanted is None:
            return None
        key = _run_key(wanted_doc)
        for folder in self.folders:
            path = run_path(folder, plan)
            if path.exists():
                try:
                    settings = read_run(path).get("settings")
                except (OSError, ValueError, EOFError):
                    settings = None
                if isinstance(settings, dict) and effective_settings(settings) == wanted:
                    return path
            for effective, path in self._folder_index(folder).get(key, []):
                if effective == wanted:
                    return path
        return None


def reused_document(source: Path, plan: PlannedRun) -> dict[str, Any]:
    """The stored run at ``source`` as ``plan``'s: its ``settings`` as ``plan`` spells them
    (the same effective settings, :func:`effective_settings`) and its ``run`` block replaced
    by ``plan.describe()`` plus ``reused_from`` (``<spec>/<run_id>`` of the source); without
    the source's ``replaced`` block (the copy replaced nothing)."""
    from localpbo_core.run_documents import settings_document

    doc = read_run(source)
    doc.pop("replaced", None)
    doc["settings"] = settings_document(plan.settings)
    origin = doc.get("run") or {}
    doc["run"] = {
        **plan.describe(),
        "reused_from": f"{origin.get('spec', source.parent.parent.name)}/"
        f"{origin.get('run_id', plan.run_id)}",
    }
    return doc


def select_runs(
    spec: ExperimentSpec,
    problems: Sequence[str] | None = None,
    algorithms: Sequence[str] | None = None,
    variants: Sequence[str] | None = None,
    seeds: Sequence[int] | None = None,
) -> list[PlannedRun]:
    """The runs of ``spec`` whose labels and seed pass the filters (None: all).

    Raises:
        SettingError: a filter names a label or seed the spec does not have.
    """
    known: dict[str, list[Any]] = {
        "--problems": [p.label for p in spec.problems],
        "--algorithms": [a.label for a in spec.algorithms],
        "--variants": [v.label for v in spec.variants],
        "--seeds": list(spec.seeds),
    }
    chosen: dict[str, Sequence[Any] | None] = {
        "--problems": problems,
        "--algorithms": algorithms,
        "--variants": variants,
        "--seeds": seeds,
    }
    for flag, values in chosen.items():
        for v in values or ():
            if v not in known[flag]:
                raise SettingError(
                    flag, f"{v!r} is not in the spec; available: {', '.join(map(str, known[flag]))}"
                )
    return spec.runs(problems, algorithms, variants, seeds)


def sweep(
    spec: ExperimentSpec,
    out: Path,
    runs: Sequence[PlannedRun] | None = None,
    max_runs: int | None = None,
    address: str | None = None,
    workers: int | None = None,
    in_process: bool = False,
    progress: bool = True,
    on_stored: Callable[[PlannedRun], None] | None = None,
    stop_on_sigterm: bool = False,
    reuse: Sequence[Path] = (),
    rerun_changed: bool = False,
    time_limit: float | None = None,
    times_from: Sequence[Path] = (),
    checkpoint_every: float | None = CHECKPOINT_EVERY_S,
) -> SweepResult:
    """Run every unfinished run of ``runs`` (default: all of ``spec``) and store each.

    Args:
        spec: the loaded spec (its copy is written to ``OUT/spec.json``).
        out: output folder; finished runs in ``OUT/runs``.
        runs: the selection (:func:`select_runs`).
        max_runs: run at most this many unfinished runs (in spec order).
        address: an existing Ray cluster (``ray.init(address=...)``); None: embedded Ray.
        workers: CPUs of the embedded Ray (default: the machine's cores).
        in_process: run sequentially in this process, without Ray.
        progress: show a progress bar with ETA.
        on_stored: called after each computed run is stored.
        stop_on_sigterm: SIGTERM interrupts the sweep like Ctrl-C while it runs (called
            from the main thread; ``localpbo sweep`` sets it).
        reuse: folders of other sweeps whose identical runs are copied, not computed
            (module docstring, "Reuse"); ``max_runs`` counts computed runs only.
        rerun_changed: run again the stored runs made by code today's is not known to
            reproduce (module docstring, "Re-run"); they count as unfinished.
        time_limit: seconds from the call (module docstring, "Time limit"): no run starts
            that the longest stored run of its group (:class:`RunTimes`) says would end
            later (it is left, in ``pending`` and ``over_time``); with ``stop_on_sigterm``
            the runs still under way at the limit are stopped as by SIGTERM
            (``time_limit_reached``).
        times_from: folders of other sweeps whose measured runs stand in for a group with
            none in ``out`` (:class:`RunTimes`), for ``time_limit``.
        checkpoint_every: seconds of a run between its checkpoints
            (``OUT/checkpoints/<run_id>.ckpt.gz``, module docstring "Checkpoints"); a run
            with a checkpoint continues from it; None: no checkpoints are written or read.

    Interrupted (``KeyboardInterrupt``: Ctrl-C, or SIGTERM with ``stop_on_sigterm``), it
    stops the runs under way and returns with ``interrupted`` set; every run finished before
    is stored, the others are ``pending`` and the same call continues with them.
    """
    from tqdm import tqdm

    began = time.monotonic()
    plans = list(spec.runs() if runs is None else runs)
    result = SweepResult()
    todo = []
    copies: list[tuple[PlannedRun, Path]] = []
    index = ReuseIndex(reuse)
    tables = rerun_tables(out) if rerun_changed else None
    stale: set[str] = set()
    for plan in plans:
        state = stored_state(out, plan, tables)
        if state == "stale":
            stale.add(plan.run_id)
            todo.append(plan)
        elif state == "finished":
            result.skipped.append(plan.run_id)
        elif index and (source := index.find(plan)) is not None:
            copies.append((plan, source))
        else:
            todo.append(plan)
    out.mkdir(parents=True, exist_ok=True)
    (out / "spec.json").write_text(json.dumps(_spec_document(spec), indent=1) + "\n")

    def held_elsewhere(plan: PlannedRun) -> None:
        result.elsewhere[plan.run_id] = (holder(out, plan.run_id) or Holder()).describe()

    for plan, source in copies:
        copying = try_claim(out, plan.run_id)
        if copying is None:
            held_elsewhere(plan)
            continue
        with copying:
            _remove_partial_writes(out, plan)
            write_run(run_path(out, plan), reused_document(source, plan))
        result.reused.append(plan.run_id)
    limit = len(todo) if max_runs is None else max_runs
    skipped_before, elsewhere_before = len(result.skipped), len(result.elsewhere)
    bar = tqdm(total=min(limit, len(todo)), disable=not progress, unit="run", dynamic_ncols=True)
    held: dict[str, Claim] = {}
    started: list[PlannedRun] = []
    queue = iter(todo)
    times = RunTimes(out, times_from) if time_limit is not None else None
    deadline = None if time_limit is None else began + time_limit
    every = CHECKPOINT_EVERY_S if checkpoint_every is None else checkpoint_every

    def checkpoint_of(plan: PlannedRun) -> Path | None:
        return None if checkpoint_every is None else checkpoint_path(out, plan)

    def passed_over() -> None:
        passed = len(result.elsewhere) - elsewhere_before + len(result.skipped) - skipped_before
        bar.total = min(limit, len(todo) - passed)
        bar.refresh()

    def claim(plan: PlannedRun) -> bool:
        """Claim ``plan`` for this sweep; False (and noted) if another sweep holds it or
        stored it meanwhile."""
        got = try_claim(out, plan.run_id)
        if got is None:
            held_elsewhere(plan)
            passed_over()
            return False
        if stored_state(out, plan, tables) == "finished":  # another sweep stored it meanwhile
            got.release()
            result.skipped.append(plan.run_id)
            passed_over()
            return False
        _remove_partial_writes(out, plan)
        held[plan.run_id] = got
        started.append(plan)
        return True

    def release(plan: PlannedRun) -> None:
        got = held.pop(plan.run_id, None)
        if got is not None:
            got.release()

    def store(plan: PlannedRun, doc: dict[str, Any]) -> None:
        path = run_path(out, plan)
        if plan.run_id in stale and tables is not None:
            old = read_run(path)
            doc = {**doc, "replaced": replaced_block(old, doc, tables.known_code(path, old))}
        if times is not None:
            times.add(plan, doc)  # before the file exists: a group read later counts it once
        write_run(path, doc)
        with contextlib.suppress(FileNotFoundError):
            checkpoint_path(out, plan).unlink()  # the run it kept is stored
        release(plan)
        result.finished.append(plan.run_id)
        segments = (doc.get("checkpoints") or {}).get("segments") or []
        if segments:
            result.resumed[plan.run_id] = int(segments[-1]["evaluations"][0]) - 1
        if plan.run_id in stale:
            result.rerun.append(plan.run_id)
        bar.set_postfix_str(plan.run_id, refresh=False)
        bar.update(1)
        if on_stored is not None:
            on_stored(plan)

    def fail(plan: PlannedRun, error: str) -> None:
        release(plan)
        result.failed[plan.run_id] = error
        bar.update(1)

    def next_plan() -> PlannedRun | None:
        """The next run to start, claimed; None when there is none (left runs are noted)."""
        for plan in queue:
            if len(started) >= limit:
                result.pending.append(plan.run_id)
                continue
            if times is not None and deadline is not None:
                longest = times.longest(plan)
                if longest is not None and not _worth_starting(
                    deadline - time.monotonic(), longest, checkpoint_of(plan), checkpoint_every
                ):
                    result.pending.append(plan.run_id)
                    result.over_time.append(plan.run_id)
                    continue
            if claim(plan):
                return plan
        return None

    try:
        with (
            _sigterm_interrupts(stop_on_sigterm),
            _hard_stop(deadline if stop_on_sigterm else None, result),
        ):
            if in_process:
                while (run := next_plan()) is not None:
                    try:
                        doc = execute_run(run, checkpoint_of(run), every)
                    except Exception as exc:  # a bug in one run must not stop the sweep
                        fail(run, f"{type(exc).__name__}: {exc}")
                        continue
                    store(run, doc)
            elif (first := next_plan()) is not None:
                _run_on_ray(
                    first,
                    next_plan,
                    address,
                    workers,
                    store,
                    fail,
                    stop_on_sigterm,
                    lambda plan: (checkpoint_of(plan), every),
                )
    except KeyboardInterrupt:
        settled = set(result.finished) | set(result.failed) | set(result.skipped)
        settled |= set(result.elsewhere) | set(result.pending)
        cut = [p.run_id for p in todo if p.run_id not in settled]
        result.pending += cut
        # the time limit's signal can land just after the last run: then nothing was cut
        result.interrupted = bool(cut) or not result.time_limit_reached
    finally:
        for got in held.values():
            got.release()
        bar.close()
    for plan in todo:
        path = checkpoint_of(plan)
        if plan.run_id in result.pending and path is not None and path.exists():
            evaluations = checkpoint_evaluations(path)
            if evaluations is not None:
                result.kept[plan.run_id] = evaluations
    return result


def checkpoint_progress(path: Path) -> tuple[int, float] | None:
    """The evaluations done and run seconds behind the checkpoint at ``path`` (None: none
    readable there)."""
    from localpbo_core.checkpoints import CheckpointError, read_header

    try:
        header = read_header(path)
        return int(header["evaluations"]), max(0.0, float(header["run_seconds"]))
    except (CheckpointError, KeyError, TypeError, ValueError):
        return None


def checkpoint_evaluations(path: Path) -> int | None:
    """The evaluations done in the checkpoint at ``path`` (None: none readable there)."""
    progress = checkpoint_progress(path)
    return None if progress is None else progress[0]


def _worth_starting(
    left: float, longest: float, checkpoint: Path | None, checkpoint_every: float | None
) -> bool:
    """Start a run with ``left`` seconds to the time limit, its group's longest run taking
    ``longest``? Yes if what is left of it fits (a run continued from its checkpoint has the
    checkpoint's seconds behind it); else, with checkpoints, yes if at least one checkpoint
    interval is left, since its progress is then kept for the next sweep."""
    progress = (
        None if checkpoint is None or not checkpoint.exists() else checkpoint_progress(checkpoint)
    )
    behind = 0.0 if progress is None else progress[1]
    if longest - behind <= left:
        return True
    return checkpoint_every is not None and left >= checkpoint_every


class RunTimes:
    """The wall seconds of the runs stored in a sweep folder, per group (the run id without
    its seed: one problem, algorithm and variant), for ``--time-limit``: a run is not started
    when the longest stored run of its group would not end before the limit.

    A group's files are read once (their ``run_seconds``; copies made by ``--reuse`` and runs
    without a measured time are passed over); runs this sweep finishes are added. A group
    with no measured run in ``out`` takes the measured runs of the same group in ``others``
    (``--times-from``), all of them together, until this sweep finishes one of its own."""

    def __init__(self, out: Path, others: Sequence[Path] = ()) -> None:
        self.out = out
        self._seconds: dict[str, list[float]] = {}
        self._others = [RunTimes(folder) for folder in others]

    @staticmethod
    def group(run_id: str) -> str:
        """``hopper__turpbo__seed3`` -> ``hopper__turpbo``."""
        return run_id.rsplit("__seed", 1)[0]

    def _group_seconds(self, group: str) -> list[float]:
        if group not in self._seconds:
            seconds: list[float] = []
            for path in sorted((self.out / "runs").glob(f"{group}__seed*{RUN_SUFFIX}")):
                if self.group(path.name[: -len(RUN_SUFFIX)]) != group:
                    continue
                try:
                    doc = read_run(path)
                except (OSError, ValueError, EOFError, SettingError):
                    continue
                measured = self._measured(doc)
                if measured is not None:
                    seconds.append(measured)
            self._seconds[group] = seconds
        return self._seconds[group]

    @staticmethod
    def _measured(doc: dict[str, Any]) -> float | None:
        value = doc.get("run_seconds")
        if (doc.get("run") or {}).get("reused_from") or not isinstance(value, int | float):
            return None
        return float(value) if value > 0 else None

    def longest(self, plan: PlannedRun) -> float | None:
        """The longest wall time of ``plan``'s group's runs, else of the same group's runs in
        the other folders (None: none measured anywhere)."""
        group = self.group(plan.run_id)
        seconds = self._group_seconds(group)
        if not seconds:
            seconds = [s for other in self._others for s in other._group_seconds(group)]
        return max(seconds) if seconds else None

    def add(self, plan: PlannedRun, doc: dict[str, Any]) -> None:
        """Count the run this sweep just finished."""
        measured = self._measured(doc)
        if measured is not None:
            self._group_seconds(self.group(plan.run_id)).append(measured)


@contextlib.contextmanager
def _hard_stop(deadline: float | None, result: SweepResult) -> Iterator[None]:
    """At ``deadline`` (``time.monotonic()``; None: never) the sweep sends itself SIGTERM,
    which stops it as a SIGTERM from outside does (the caller handles SIGTERM), and notes
    ``result.time_limit_reached``. Leaving the block cancels it."""
    if deadline is None:
        yield
        return
    armed = threading.Lock()
    active = [True]

    def fire() -> None:
        with armed:
            if active[0]:
                result.time_limit_reached = True
                os.kill(os.getpid(), signal.SIGTERM)

    timer = threading.Timer(max(0.0, deadline - time.monotonic()), fire)
    timer.daemon = True
    timer.start()
    try:
        yield
    finally:
        with armed:
            active[0] = False
        timer.cancel()


def parse_duration(text: str, field: str = "--time-limit") -> float:
    """Seconds in ``"5400"``, ``"90m"``, ``"1h30m"``, ``"2h"``, ``"45s"`` or ``"1d"``.

    Raises:
        SettingError: naming ``field``.
    """
    units = {"d": 86400.0, "h": 3600.0, "m": 60.0, "s": 1.0, "": 1.0}
    parts = re.fullmatch(r"(?:\d+(?:\.\d+)?[dhms]?)+", text.strip())
    total = 0.0
    if parts:
        for number, unit in re.findall(r"(\d+(?:\.\d+)?)([dhms]?)", text.strip()):
            total += float(number) * units[unit]
    if not parts or total <= 0:
        raise SettingError(
            field, f"expected a positive duration such as 5400, 90m or 1h30m, got {text!r}"
        )
    return total


LOOPBACK_ONLY_ENV = "RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER"
"""Ray's switch between a single-machine head (every server on the loopback address; the
default on Windows and macOS) and a cluster head (servers on all interfaces). The embedded
Ray sets it to ``0`` before Ray is imported, unless the user set it."""


_SESSION: Path | None = None
"""The private temporary folder of the embedded Ray this process started, if it runs
(:mod:`localpbo_core.ray_cleanup`)."""


def start_ray(address: str | None, workers: int | None, keep_sigterm_handler: bool = False) -> bool:
    """Connect to the Ray cluster at ``address``, or start the embedded one (``workers`` CPUs,
    servers on the loopback address only, no dashboard) unless Ray is already running.
    Returns True if this call started or connected Ray (the caller stops it: :func:`stop_ray`).

    The embedded Ray never joins a cluster it finds on this machine (``address="local"``),
    runs in a private temporary folder under a watchdog that stops its processes and removes
    the folder once this process ends, however it ends (:mod:`localpbo_core.ray_cleanup`),
    and first cleans up after earlier drivers that were killed with their watchdogs.
    ``keep_sigterm_handler``: ``ray.init`` leaves the process's SIGTERM handler as it is
    (by default it installs its own, which calls ``sys.exit``)."""
    global _SESSION
    if address is None:
        os.environ.setdefault(LOOPBACK_ONLY_ENV, "0")
    import ray

    if ray.is_initialized():
        return False
    kwargs: dict[str, Any] = {"include_dashboard": False, "log_to_driver": False}
    if address is None:
        from localpbo_core import ray_cleanup

        ray_cleanup.clean_stale()
        _SESSION = folder = ray_cleanup.make_temp_dir()
        ray_cleanup.start_watchdog(folder)
        kwargs["num_cpus"] = workers or os.cpu_count() or 1
        kwargs["_temp_dir"] = str(folder)
    with _without_ray_sigterm_handler() if keep_sigterm_handler else contextlib.nullcontext():
        ray.init(address=address or "local", logging_level=logging.ERROR, **kwargs)
    return True


ADDRESS_TIMEOUT_S = 5.0
"""Seconds ``localpbo sweep --address HOST:PORT`` waits for a TCP connection to the cluster's
head before it refuses the address (Ray itself would retry for minutes)."""


def check_address(address: str) -> None:
    """Refuse ``--address HOST:PORT`` when nothing accepts a connection there; other forms
    (``auto``, ``ray://...``) are left to Ray.

    Raises:
        SettingError: ``--address``, naming the address and why.
    """
    host, sep, port = address.rpartition(":")
    if not sep or not host or "/" in address or not port.isdigit():
        return
    try:
        socket.create_connection((host.strip("[]"), int(port)), ADDRESS_TIMEOUT_S).close()
    except OSError as exc:
        raise SettingError(
            "--address", f"no Ray cluster answers at {address} ({exc.strerror or exc})"
        ) from None


def stop_ray() -> None:
    """``ray.shutdown()``; after the embedded Ray, also stop any of its processes still
    running and remove its temporary folder."""
    global _SESSION
    import ray

    ray.shutdown()
    if _SESSION is not None:
        from localpbo_core import ray_cleanup

        ray_cleanup.clean(_SESSION, ray_cleanup.WATCHDOG_GRACE_S)
        _SESSION = None


def _run_on_ray(
    first: PlannedRun,
    next_plan: Callable[[], PlannedRun | None],
    address: str | None,
    workers: int | None,
    store: Callable[[PlannedRun, dict[str, Any]], None],
    fail: Callable[[PlannedRun, str], None],
    stop_on_sigterm: bool,
    checkpointing: Callable[[PlannedRun], tuple[Path | None, float]],
) -> None:
    with _stops_deferred(stop_on_sigterm) as stopped:
        try:
            started = start_ray(address, workers, keep_sigterm_handler=stop_on_sigterm)
        except (KeyboardInterrupt, SystemExit):
            stop_ray()  # whatever of Ray had started
            raise
    if stopped:
        # Ctrl-C or SIGTERM while Ray started: it was let finish starting, now it stops
        if started:
            stop_ray()
        raise KeyboardInterrupt
    import ray

    try:
        # after ray.init, whose own SIGTERM handler exits at once
        with _sigterm_interrupts(stop_on_sigterm):
            task = ray.remote(num_cpus=1, max_retries=MAX_RETRIES)(execute_run)
            slots = max(1, int(ray.cluster_resources().get("CPU", 1)))
            refs = {task.remote(first, *checkpointing(first)): first}
            while refs:
                while len(refs) < slots and (plan := next_plan()) is not None:
                    refs[task.remote(plan, *checkpointing(plan))] = plan
                done, _ = ray.wait(list(refs), num_returns=1)
                for ref in done:
                    plan = refs.pop(ref)
                    try:
                        doc = ray.get(ref)
                    except ray.exceptions.RayError as exc:
                        fail(plan, str(exc).strip().splitlines()[-1])
                        continue
                    store(plan, doc)
    finally:
        if started:
            stop_ray()


def _spec_path(path: str) -> str:
    """A bundled spec as its path in the repository (no machine-specific prefix)."""
    bundled = Path(__file__).resolve().parent / "experiments"
    resolved = Path(path).resolve()
    if resolved.parent == bundled:
        return f"localpbo_core/experiments/{resolved.name}"
    return path


def _spec_document(spec: ExperimentSpec) -> dict[str, Any]:
    return {
        "name": spec.name,
        "paper": spec.paper,
        "path": _spec_path(spec.path) if spec.path else spec.path,
        "seeds": list(spec.seeds),
        "problems": [p.label for p in spec.problems],
        "algorithms": [a.label for a in spec.algorithms],
        "variants": [v.label for v in spec.variants if v.label],
        "within_model": spec.within_model,
    }


def format_dry_run(
    out: Path,
    plans: Sequence[PlannedRun],
    max_runs: int | None,
    reuse: Sequence[Path] = (),
    rerun_changed: bool = False,
    checkpoints: bool = True,
) -> str:
    """One line per run: its id, state (finished / reuse / will run / will rerun / under way
    in another sweep / left for later) and budget; a run that will continue a checkpoint
    (unless ``checkpoints`` is False) says from how many evaluations."""
    lines = [f"{'run':<48} {'state':<10} {'budget':>7} {'init':>5}"]
    counts = dict.fromkeys(("finished", "reuse", "will run", "will rerun", "under way", "later"), 0)
    if not reuse:
        del counts["reuse"]
    if not rerun_changed:
        del counts["will rerun"]
    started = 0
    index = ReuseIndex(reuse)
    tables = rerun_tables(out) if rerun_changed else None
    for plan in plans:
        stored = stored_state(out, plan, tables)
        if stored == "finished":
            state = "finished"
        elif stored == "missing" and index and index.find(plan) is not None:
            state = "reuse"
        elif holder(out, plan.run_id) is not None:
            state = "under way"
        elif max_runs is None or started < max_runs:
            state, started = "will rerun" if stored == "stale" else "will run", started + 1
        else:
            state = "later"
        counts[state] += 1
        budget = "default" if plan.settings.budget is None else str(plan.settings.budget)
        line = f"{plan.run_id:<48} {state:<10} {budget:>7} {plan.settings.initial_design:>5}"
        if checkpoints and state.startswith("will"):
            done = checkpoint_evaluations(checkpoint_path(out, plan))
            line += "" if done is None else f"  (continues its checkpoint at {done})"
        lines.append(line)
    if not counts["under way"]:
        del counts["under way"]
    lines.append(", ".join(f"{n} {k}" for k, n in counts.items()) + f" ({len(plans)} runs)")
    return "\n".join(lines)


def check_writable(out: Path) -> None:
    """Refuse an output folder the sweep cannot make or write (runs and claims), before any
    run is computed.

    Raises:
        SettingError: field ``--out``.
    """
    probe = out / CLAIMS_DIR / f".write-check.{os.getpid()}"
    try:
        (out / "runs").mkdir(parents=True, exist_ok=True)
        probe.parent.mkdir(exist_ok=True)
        probe.write_bytes(b"")
        probe.unlink()
        (out / "runs" / probe.name).write_bytes(b"")
        (out / "runs" / probe.name).unlink()
    except OSError as exc:
        raise SettingError("--out", f"cannot write runs to {out}: {exc.strerror or exc}") from None


def main_sweep(args: Any) -> int:
    """The ``localpbo sweep`` command (its arguments: :mod:`localpbo_core.cli`)."""
    from localpbo_core.arguments import parse_seeds
    from localpbo_core.experiments import load_spec

    def labels(text: str | None) -> list[str] | None:
        return None if not text else [t.strip() for t in text.split(",") if t.strip()]

    spec = load_spec(args.spec)
    seeds = None if args.seeds is None else parse_seeds(args.seeds)
    if args.max_runs is not None and args.max_runs < 0:
        raise SettingError("--max-runs", f"must be >= 0, got {args.max_runs}")
    plans = select_runs(
        spec, labels(args.problems), labels(args.algorithms), labels(args.variants), seeds
    )
    out = Path(args.out)
    reuse = [Path(folder) for folder in args.reuse or ()]
    times_from = [Path(folder) for folder in args.times_from or ()]
    for name, folders in (("--reuse", reuse), ("--times-from", times_from)):
        for folder in folders:
            if not folder.is_dir():
                raise SettingError(name, f"{folder} is not a folder")
    if times_from and args.time_limit is None:
        raise SettingError("--times-from", "only --time-limit reads it; give one")
    every = parse_duration(args.checkpoint_every, "--checkpoint-every")
    if args.dry_run:
        print(
            format_dry_run(
                out, plans, args.max_runs, reuse, args.rerun_changed, not args.no_checkpoints
            )
        )
        return 0
    time_limit = None if args.time_limit is None else parse_duration(args.time_limit)
    check_writable(out)
    if args.address is not None and not args.in_process:
        check_address(args.address)
    start = time.perf_counter()
    result = sweep(
        spec,
        out,
        plans,
        max_runs=args.max_runs,
        address=args.address,
        workers=args.workers,
        in_process=args.in_process,
        progress=not args.no_progress,
        stop_on_sigterm=True,
        reuse=reuse,
        rerun_changed=args.rerun_changed,
        time_limit=time_limit,
        times_from=times_from,
        checkpoint_every=None if args.no_checkpoints else every,
    )
    reused = f"{len(result.reused)} reused, " if reuse else ""
    rerun = f" ({len(result.rerun)} of them rerun)" if args.rerun_changed else ""
    elsewhere = f", {len(result.elsewhere)} under way in another sweep" if result.elsewhere else ""
    print(
        f"{spec.name}: {_count(len(result.finished), 'run')} finished{rerun}, {reused}"
        f"{len(result.skipped)} "
        f"already stored, {len(result.failed)} failed, {len(result.pending)} left{elsewhere} "
        f"({time.perf_counter() - start:.1f} s); results in {out / 'runs'}"
    )
    for run_id, error in sorted(result.failed.items()):
        print(f"FAILED {run_id}: {error}")
    for run_id, who in sorted(result.elsewhere.items()):
        print(f"UNDER WAY {run_id}: claimed by {who}; not run here")
    if result.over_time:
        print(
            f"not started, would end after --time-limit {args.time_limit}: "
            + ", ".join(result.over_time)
        )
    for run_id, evaluations in sorted(result.resumed.items()):
        print(f"CONTINUED {run_id}: from its checkpoint at {evaluations} evaluations")
    for run_id, evaluations in sorted(result.kept.items()):
        print(f"CHECKPOINT {run_id}: {evaluations} evaluations kept; the same command continues")
    if result.time_limit_reached and result.interrupted:
        print(f"--time-limit {args.time_limit} reached: the runs under way were stopped")
    if result.interrupted:
        print("interrupted: the same command continues with the runs left", file=sys.stderr)
        return EXIT_INTERRUPTED
    return 1 if result.failed else 0


def _count(n: int, noun: str) -> str:
    """``n`` and ``noun``, plural unless ``n`` is 1 ("1 run", "3 runs")."""
    return f"{n} {noun}" if n == 1 else f"{n} {noun}s"


EXIT_INTERRUPTED = 130
"""Exit status of an interrupted sweep (128 + SIGINT, as shells report Ctrl-C)."""


@contextlib.contextmanager
def _stops_deferred(enabled: bool) -> Iterator[list[int]]:
    """If ``enabled`` (and in the main thread), SIGINT and SIGTERM are only noted in the block
    (the list it yields gets their numbers) and the caller stops after it.

    Made for ``ray.init``: an exception raised by a signal handler while Ray starts lands
    wherever the interpreter is, and there it may be swallowed (in a fork callback Python
    prints "Exception ignored" and goes on, so the sweep would run to the end) or leave Ray's
    driver half connected (its C++ core then aborts the process at exit); for the same reason
    the caller keeps Ray's own SIGTERM handler (``sys.exit``) out of ``ray.init``
    (:func:`start_ray`). The handlers from before are restored after the block.

    A block that has not ended ``STOP_WAIT_S`` after the first signal (a connection that
    hangs), or a second signal, ends the process at once with 130, after removing what the
    embedded Ray had started (:func:`abandon_ray`)."""
    noted: list[int] = []
    if not enabled or threading.current_thread() is not threading.main_thread():
        yield noted
        return
    inside = threading.Event()
    inside.set()

    def give_up() -> None:
        if inside.is_set():
            abandon_ray()

    def note(signum: int, frame: Any) -> None:
        noted.append(signum)
        if len(noted) > 1:
            give_up()
        else:
            timer = threading.Timer(STOP_WAIT_S, give_up)
            timer.daemon = True
            timer.start()

    previous = {sig: signal.signal(sig, note) for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield noted
    finally:
        inside.clear()
        for sig, handler in previous.items():
            signal.signal(sig, handler)


STOP_WAIT_S = 10.0
"""Seconds a Ray start or connection may still take after Ctrl-C or SIGTERM before the sweep
gives up on it and ends at once."""


def abandon_ray() -> NoReturn:
    """End the process at once with 130 (an interrupted sweep; nothing of it was stored yet),
    after stopping the processes of the embedded Ray it started, if any."""
    from localpbo_core.stopping import exit_now

    print("interrupted while Ray was starting; nothing was run", file=sys.stderr)
    if _SESSION is not None:
        from localpbo_core import ray_cleanup

        ray_cleanup.clean(_SESSION, ray_cleanup.WATCHDOG_GRACE_S)
    exit_now(EXIT_INTERRUPTED)


@contextlib.contextmanager
def _without_ray_sigterm_handler() -> Iterator[None]:
    """``ray.init`` installs none of its SIGTERM handlers in the block, so a SIGTERM while Ray
    starts reaches the caller's handler alone.

    Ray has two: a Python one (``ray._private.utils.set_sigterm_handler``, replaced here by a
    no-op), which calls ``sys.exit``; and the C++ failure signal handler of its driver
    (absl's), which prints a stack, passes the signal on, then arms a 3-s alarm that aborts
    the process (exit -6, often before anything was cleaned up or said) unless the process
    has ended by then; it stays out while ``ray._private.ray_constants``'s
    ``RAY_DISABLE_FAILURE_SIGNAL_HANDLER`` is true (Ray's own switch, read when the driver's
    core worker starts; Ray's worker processes keep theirs). A Ray without either attribute
    keeps that handler as before."""
    import ray._private.ray_constants as ray_constants
    import ray._private.utils as ray_utils

    patched: list[tuple[Any, str, Any]] = []
    for module, name, value in (
        (ray_utils, "set_sigterm_handler", lambda handler: None),
        (ray_constants, "RAY_DISABLE_FAILURE_SIGNAL_HANDLER", True),
    ):
        if hasattr(module, name):
            patched.append((module, name, getattr(module, name)))
            setattr(module, name, value)
    try:
        yield
    finally:
        for module, name, original in patched:
            setattr(module, name, original)


@contextlib.contextmanager
def _sigterm_interrupts(enabled: bool) -> Iterator[None]:
    """If ``enabled`` (and in the main thread), SIGTERM raises ``KeyboardInterrupt`` in the
    block, so it stops the sweep like Ctrl-C; the previous handler is restored after."""

    def interrupt(signum: int, frame: Any) -> None:
        raise KeyboardInterrupt

    if not enabled or threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = signal.signal(signal.SIGTERM, interrupt)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)
