"""Which code made a stored run.

A run's outcome is a function of its settings and of the code that executed it: the session,
the optimizer, the surrogate, the problem and (for policy tasks) the simulator. Each stored run
carries a ``code`` block with

* ``digest``: SHA-256 over the source files a run executes (:data:`RUN_SOURCES`, every
  ``*.py`` file below them, in sorted order, path and bytes), so two checkouts that would run
  identically share a digest whatever their commits, and a change to a report or a CLI does
  not mark runs as stale;
* ``algorithm_digest``: the same over the files of the run's own algorithm (its module and
  the modules every algorithm shares, :func:`algorithm_sources`), which tells whether *this*
  algorithm changed since the run was stored;
* ``commit``: the git commit of the checkout, when there is one, with ``dirty`` when the run
  sources differed from it.

:func:`stale_algorithms` compares stored blocks with today's code; the results page flags
the groups it finds. :func:`run_code_state` says of one stored run whether today's code would
make it again ("current", "same behaviour") or not ("changed since", "none stored"); a run
stored without a block is dated by the commit that stored it (``stored_code.json``,
:func:`stored_by_commit`), and a recorded re-run that gave the same trace bit for bit with
the old and today's code (``equivalent_code.json``, :func:`equivalent_digests`) makes an older
block "same behaviour". ``localpbo sweep --rerun-changed`` runs again every run whose state is
"changed since" or "none stored", and the re-run carries a ``replaced`` block
(:func:`replaced_block`): which code made the run it replaced, how many leading candidates the
two share bit for bit, whether their duels got the same answers, and the old final values,
so what a re-run changed stays on record after the old file is gone. Re-runs stored before
re-runs carried it are described by ``replaced_runs.json``
(:mod:`localpbo_core.experiments.replaced`, from the repository's history).

The same code does not make the same run everywhere: floating-point kernels differ between
CPUs (torch picks its vector kernels by the CPU's instruction set, MKL its code path by the
CPU), between library versions and between thread counts, and a last-bit difference in one
candidate is amplified by the duels' noise draws and the model's refits. So each stored run
also carries a ``platform`` block (:func:`platform_block`): the CPU, torch's kernel level
(``AVX2``, ``AVX512``, ...), torch's thread count, the versions of the numerical libraries
and the environment variables that change their kernels. A re-run's ``replaced`` block says
whether the run it replaced came from the same platform (``same_platform``), so a re-run that
parts from a run of the same code reads as a machine's doing only when the platforms differ.
"""

from __future__ import annotations

import contextlib
import functools
import hashlib
import importlib.metadata
import json
import os
import platform
import subprocess
from collections.abc import Iterable
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
"""The checkout (or installed tree) holding ``localpbo_core`` and ``sims``."""

RUN_SOURCES = (
    "localpbo_core/optimizers",
    "localpbo_core/surrogate",
    "localpbo_core/problems",
    "localpbo_core/session.py",
    "localpbo_core/settings.py",
    "localpbo_core/seeds.py",
    "localpbo_core/loop.py",
    "localpbo_core/threads.py",
    "localpbo_core/validation.py",
    "localpbo_core/space.py",
    "sims",
)
"""What a run executes: changing any of these may change a stored run's trace."""

SHARED_ALGORITHM_SOURCES = (
    "localpbo_core/optimizers/preference_optimizer.py",
    "localpbo_core/optimizers/base.py",
    "localpbo_core/optimizers/recommendation.py",
    "localpbo_core/optimizers/registry.py",
    "localpbo_core/optimizers/botorch_adapter.py",
    "localpbo_core/optimizers/surrogate_refit.py",
    "localpbo_core/surrogate",
    "localpbo_core/session.py",
    "localpbo_core/seeds.py",
    "localpbo_core/loop.py",
)
"""Every algorithm's common ground (ask/tell base, surrogate, run protocol)."""

ALGORITHM_MODULES: dict[str, tuple[str, ...]] = {
    "gipbo": ("gipbo.py", "gi_acquisition.py", "local_phase.py"),
    "gipbor": ("gipbo.py", "gi_acquisition.py", "local_phase.py"),
    "prefsqp": ("prefsqp.py", "local_phase.py", "acquisition.py"),
    "turpbo": ("turpbo.py", "gp_acquisition.py", "trust_region.py", "acquisition.py"),
    "qeubo": ("qeubo.py", "gp_acquisition.py", "acquisition.py"),
    "hbei": ("hbei.py", "acquisition.py"),
    "glisp": ("glisp.py", "glisp_lp.py", "glisp_pso.py", "glisp_acquisition.py"),
    "sobol": ("sobol.py",),
    "hybrid": (
        "hybrid.py",
        "turpbo.py",
        "gp_acquisition.py",
        "trust_region.py",
        "acquisition.py",
        "prefsqp.py",
        "local_phase.py",
        "gi_acquisition.py",
    ),
}
"""Each algorithm's own modules under ``localpbo_core/optimizers``."""


def _files(entries: Iterable[str]) -> list[Path]:
    out: set[Path] = set()
    for entry in entries:
        path = ROOT / entry
        if path.is_dir():
            out.update(p for p in path.rglob("*.py") if "__pycache__" not in p.parts)
        elif path.exists():
            out.add(path)
    return sorted(out)


def digest_of(files: Iterable[tuple[str, bytes]]) -> str:
    """SHA-256 (first 16 hex digits) over ``(path, bytes)`` pairs in sorted path order: the
    digest of the module docstring, whether the files come from the work tree or from a
    commit (:func:`localpbo_core.experiments.stored_code.code_at`)."""
    h = hashlib.sha256()
    for path, data in sorted(files):
        h.update(path.encode() + b"\0")
        h.update(data + b"\0")
    return h.hexdigest()[:16]


def _digest(entries: Iterable[str]) -> str:
    return digest_of((p.relative_to(ROOT).as_posix(), p.read_bytes()) for p in _files(entries))


def algorithm_sources(algorithm: str) -> tuple[str, ...]:
    """The files whose change may change ``algorithm``'s runs (its own and the shared ones;
    an unknown name gets every run source)."""
    own = ALGORITHM_MODULES.get(algorithm)
    if own is None:
        return RUN_SOURCES
    return SHARED_ALGORITHM_SOURCES + tuple(f"localpbo_core/optimizers/{m}" for m in own)


@functools.cache
def _commit() -> tuple[str | None, bool]:
    try:
        head = subprocess.run(
            ["git", "-C", str(ROOT), "rev-parse", "HEAD"],
            capture_output=True,
            text=True,
            timeout=10,
            check=True,
        ).stdout.strip()
        dirty = subprocess.run(
            ["git", "-C", str(ROOT), "status", "--porcelain", "--", *RUN_SOURCES],
            capture_output=True,
            text=True,
            timeout=10,
            check=True,
        ).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return None, False
    return head or None, bool(dirty)


@functools.cache
def code_block(algorithm: str) -> dict[str, Any]:
    """The ``code`` block stored with a run of ``algorithm`` (module docstring)."""
    commit, dirty = _commit()
    return {
        "digest": _digest(RUN_SOURCES),
        "algorithm_digest": _digest(algorithm_sources(algorithm)),
        "commit": commit,
        "dirty": dirty,
    }


NUMERIC_LIBRARIES = (
    "numpy",
    "scipy",
    "torch",
    "gpytorch",
    "linear_operator",
    "botorch",
    "mujoco",
    "glis",
)
"""The distributions whose kernels a run's numbers go through (those installed are recorded)."""

NUMERIC_VARIABLES = (
    "ATEN_CPU_CAPABILITY",
    "MKL_CBWR",
    "MKL_ENABLE_INSTRUCTIONS",
    "MKL_DEBUG_CPU_TYPE",
    "OPENBLAS_CORETYPE",
)
"""Environment variables that choose other floating-point kernels (recorded when set)."""


CPU_FLAGS = ("sse4_2", "avx", "fma", "avx2", "avx512f", "avx512dq", "avx512vl", "avx512_bf16")
"""The instruction-set flags that decide which vector kernels MKL and torch may pick (those the
CPU has are recorded: a virtual machine often names only the CPU's family)."""


@functools.cache
def _cpu() -> tuple[str, tuple[str, ...]]:
    model, flags = "", set[str]()
    with (
        contextlib.suppress(OSError),
        open("/proc/cpuinfo", encoding="utf-8", errors="replace") as fh,
    ):
        for line in fh:
            key, _, value = line.partition(":")
            if key.strip() == "model name" and not model:
                model = value.strip()
            elif key.strip() == "flags" and not flags:
                flags = set(value.split())
    return model or platform.processor() or platform.machine(), tuple(
        f for f in CPU_FLAGS if f in flags
    )


@functools.cache
def _libraries() -> dict[str, str]:
    out: dict[str, str] = {}
    for name in NUMERIC_LIBRARIES:
        try:
            out[name] = importlib.metadata.version(name)
        except importlib.metadata.PackageNotFoundError:
            continue
    return out


def _host() -> dict[str, Any]:
    """The fields of :func:`platform_block` known without importing torch."""
    model, flags = _cpu()
    return {
        "cpu": model,
        "cpu_flags": " ".join(flags),
        "machine": platform.machine(),
        "python": platform.python_version(),
        "libraries": _libraries(),
        "environment": {k: os.environ[k] for k in NUMERIC_VARIABLES if k in os.environ},
    }


def _flat(block: dict[str, Any]) -> dict[str, str]:
    """``block`` with its nested dicts spelled ``key.name`` and every value a string."""
    out: dict[str, str] = {}
    for key, value in block.items():
        if isinstance(value, dict):
            out.update({f"{key}.{k}": str(v) for k, v in value.items()})
        else:
            out[key] = str(value)
    return out


def platform_block() -> dict[str, Any]:
    """The ``platform`` block stored with a run (module docstring): ``cpu`` (the model name),
    ``cpu_flags`` (the CPU's :data:`CPU_FLAGS`, space-separated), ``machine`` (the
    architecture), ``cpu_capability`` (torch's vector-kernel level),
    ``torch_threads``, ``python``, ``libraries`` (name to version, :data:`NUMERIC_LIBRARIES`)
    and ``environment`` (the :data:`NUMERIC_VARIABLES` that are set). Two runs of the same
    code and settings whose blocks are equal are expected to agree bit for bit."""
    import torch

    return {
        **_host(),
        "cpu_capability": str(torch.backends.cpu.get_cpu_capability()),
        "torch_threads": int(torch.get_num_threads()),
    }


def recording_platform() -> dict[str, str]:
    """Where a bag is recorded, as an MCAP metadata record (string values): the fields of
    :func:`platform_block` that a process can know without importing torch (the CPU and its
    flags, the architecture, Python, ``libraries.<name>``, ``environment.<name>``) and
    ``code.digest`` (:data:`RUN_SOURCES`) and ``code.commit``. torch's kernel level follows
    from the flags and ``ATEN_CPU_CAPABILITY``; thread counts are the optimizer process's
    (one per pool, :mod:`localpbo_core.threads`), not the recorder's."""
    commit, dirty = _commit()
    return {
        **_flat(_host()),
        "code.digest": _digest(RUN_SOURCES),
        "code.commit": f"{commit or ''}{'+dirty' if dirty else ''}",
    }


def recorded_elsewhere(recorded: dict[str, str]) -> list[str]:
    """What differs between the platform a bag was recorded on (its :func:`recording_platform`
    record) and this process's, ignoring the commit (other commits with the same
    ``code.digest`` run the same code); empty when nothing does."""
    here = recording_platform()
    return [
        line for line in platform_changes(recorded, here) if not line.startswith("code.commit:")
    ]


def platform_changes(old: dict[str, Any], new: dict[str, Any]) -> list[str]:
    """What differs between two ``platform`` blocks, one ``"field: old -> new"`` per field
    (library versions and environment variables one by one); empty when they are equal."""
    a, b = _flat(old), _flat(new)
    return [
        f"{k}: {a.get(k, '-')} -> {b.get(k, '-')}"
        for k in sorted(set(a) | set(b))
        if a.get(k) != b.get(k)
    ]


def stale_algorithms(docs: Iterable[dict[str, Any]]) -> dict[str, str]:
    """Algorithms whose stored runs were made by other code than today's.

    Returns ``{algorithm: reason}``: ``"no code version stored"`` for runs stored before
    runs carried one, ``"changed since stored"`` when the stored ``algorithm_digest`` differs
    from today's. Copies (``reused_from``) are judged by the block they carry.
    """
    out: dict[str, str] = {}
    for doc in docs:
        algorithm = str((doc.get("settings") or {}).get("algorithm"))
        code = doc.get("code")
        if not isinstance(code, dict):
            out.setdefault(algorithm, "no code version stored")
        elif code.get("algorithm_digest") != code_block(algorithm)["algorithm_digest"]:
            out[algorithm] = "changed since stored"
    return out


CODE_CURRENT = "current"
"""The run's algorithm sources are today's."""
CODE_SAME = "same behaviour"
"""They changed, but re-runs with both codes on one machine gave the same trace bit for bit."""
CODE_CHANGED = "changed since"
"""They changed after the run was stored: a re-run may differ."""
CODE_NONE = "none stored"
"""No code version is known for the run."""
STALE_STATES = (CODE_CHANGED, CODE_NONE)
"""The states of runs that today's code is not known to make again."""


def known_code(
    doc: dict[str, Any],
    stored_by: tuple[str, dict[str, Any]] | None,
    pairs: dict[str, set[tuple[str, str]]],
) -> dict[str, Any] | None:
    """The code block known for the stored run ``doc``: its own, or for a run stored without
    one the digests of the commit that stored it (``stored_by``, an entry of
    :func:`stored_by_commit`, marked ``stored_by_commit``); None if neither is known.
    ``same_behaviour`` is set when ``pairs`` (:func:`equivalent_digests`) lead from its
    algorithm digest to today's (:func:`same_behaviour`)."""
    algorithm = str(doc["settings"]["algorithm"])
    code = doc.get("code")
    if isinstance(code, dict):
        block = dict(code)
    elif stored_by is not None and algorithm in stored_by[1]["algorithms"]:
        commit, digests = stored_by
        block = {
            "digest": digests["digest"],
            "algorithm_digest": digests["algorithms"][algorithm],
            "commit": commit,
            "dirty": False,
            "stored_by_commit": True,
        }
    else:
        return None
    if same_behaviour(algorithm, str(block.get("algorithm_digest")), pairs):
        block["same_behaviour"] = True
    return block


def code_state(algorithm: str, block: dict[str, Any] | None) -> str:
    """:data:`CODE_CURRENT`, :data:`CODE_SAME`, :data:`CODE_CHANGED` or :data:`CODE_NONE`
    for a run of ``algorithm`` whose known code block (:func:`known_code`) is ``block``."""
    if block is None:
        return CODE_NONE
    if block.get("algorithm_digest") == code_block(algorithm)["algorithm_digest"]:
        return CODE_CURRENT
    return CODE_SAME if block.get("same_behaviour") else CODE_CHANGED


class ProvenanceTables:
    """The ``stored_code.json`` and ``equivalent_code.json`` files of some folders, read
    once: what :func:`run_code_state` needs besides a run's document."""

    def __init__(self, folders: Iterable[Path]) -> None:
        self.by_commit: dict[Path, tuple[str, dict[str, Any]]] = {}
        self.pairs: dict[str, set[tuple[str, str]]] = {}
        for folder in folders:
            self.by_commit.update(stored_by_commit(folder / "stored_code.json"))
            for algorithm, found in equivalent_digests(folder / "equivalent_code.json").items():
                self.pairs.setdefault(algorithm, set()).update(found)

    def known_code(self, path: Path, doc: dict[str, Any]) -> dict[str, Any] | None:
        """:func:`known_code` of the run stored at ``path``."""
        return known_code(doc, self.by_commit.get(path.resolve()), self.pairs)


def run_code_state(path: Path, doc: dict[str, Any], tables: ProvenanceTables) -> str:
    """:func:`code_state` of the run ``doc`` stored at ``path``."""
    return code_state(str(doc["settings"]["algorithm"]), tables.known_code(path, doc))


def stored_by_commit(table: Path) -> dict[Path, tuple[str, dict[str, Any]]]:
    """The runs of a ``stored_code.json`` file (:mod:`localpbo_core.experiments.stored_code`):
    ``{resolved run path: (commit that stored it, that commit's digests)}``; empty if the
    file does not exist."""
    if not table.is_file():
        return {}
    doc = json.loads(table.read_text())
    commits = doc["commits"]
    return {
        (table.parent / rel).resolve(): (commit, commits[commit])
        for rel, commit in doc["runs"].items()
    }


def equivalent_digests(table: Path) -> dict[str, set[tuple[str, str]]]:
    """``{algorithm: {(old digest, new digest)}}`` from an ``equivalent_code.json`` file
    (``python -m localpbo_core.experiments.drift --why --record``): the pairs whose re-runs
    on one machine gave the same candidates bit for bit; empty if the file does not exist."""
    if not table.is_file():
        return {}
    out: dict[str, set[tuple[str, str]]] = {}
    for entry in json.loads(table.read_text()):
        if entry["identical"] == entry["candidates"]:
            out.setdefault(entry["algorithm"], set()).add((entry["from"], entry["to"]))
    return out


def same_behaviour(algorithm: str, digest: str, pairs: dict[str, set[tuple[str, str]]]) -> bool:
    """True if a chain of equivalent pairs leads from ``digest`` to today's
    ``algorithm_digest`` of ``algorithm``."""
    today = code_block(algorithm)["algorithm_digest"]
    neighbours: dict[str, set[str]] = {}
    for a, b in pairs.get(algorithm, set()):
        neighbours.setdefault(a, set()).add(b)
        neighbours.setdefault(b, set()).add(a)
    seen, frontier = {digest}, [digest]
    while frontier:
        node = frontier.pop()
        if node == today:
            return True
        fresh = neighbours.get(node, set()) - seen
        seen |= fresh
        frontier.extend(sorted(fresh))
    return False


def identical_candidates(a: dict[str, Any], b: dict[str, Any]) -> tuple[int, float]:
    """Leading candidates of the run documents ``a`` and ``b`` equal bit for bit, and the
    largest coordinate gap at the first that differs (0 if none does, inf if its dimension
    differs)."""
    xs = [np.asarray(c["native"], dtype=np.float64) for c in a["candidates"]]
    ys = [np.asarray(c["native"], dtype=np.float64) for c in b["candidates"]]
    same = 0
    for x, y in zip(xs, ys, strict=False):
        if x.shape == y.shape and np.array_equal(x, y):
            same += 1
            continue
        return same, float(np.max(np.abs(x - y))) if x.shape == y.shape else float("inf")
    return same, 0.0


def _answer_keys(doc: dict[str, Any]) -> list[tuple[Any, ...]]:
    """Each duel's pair, winner and kind (runs stored before answers carried a kind had only
    decisive ones)."""
    return [
        (a["first"], a["second"], a.get("winner"), a.get("kind", "decisive"))
        for a in doc["answers"]
    ]


def replaced_block(
    old: dict[str, Any], new: dict[str, Any], old_code: dict[str, Any] | None
) -> dict[str, Any]:
    """The ``replaced`` block of the re-run ``new`` of the stored run ``old``, whose known code
    (:func:`known_code`) is ``old_code``:

    * ``commit``, ``algorithm_digest``, ``stored_by_commit``: the old run's code (None when
      unknown; ``stored_by_commit`` when it is dated by the commit that stored it);
    * ``candidates`` (the old run's count) and ``identical``: leading candidates equal bit for
      bit; ``first_gap``: the largest coordinate gap where they first part (None: the
      dimension differs);
    * ``same_answers``: every duel has the same first, second, winner and kind;
    * ``same_platform``: the two runs' ``platform`` blocks (:func:`platform_block`) are equal
      (None when the old run has none);
    * ``best_seen``, ``cumulative``: the old run's final best-seen and cumulative true values.
    """
    identical, gap = identical_candidates(old, new)
    code = old_code or {}
    return {
        "commit": code.get("commit"),
        "algorithm_digest": code.get("algorithm_digest"),
        "stored_by_commit": bool(code.get("stored_by_commit")),
        "candidates": len(old["candidates"]),
        "identical": identical,
        "first_gap": gap if np.isfinite(gap) else None,
        "same_answers": _answer_keys(old) == _answer_keys(new),
        "same_platform": (
            old["platform"] == new.get("platform")
            if isinstance(old.get("platform"), dict)
            else None
        ),
        "best_seen": float(old["records"][-1]["best_seen"]),
        "cumulative": float(old["records"][-1]["cumulative"]),
    }
