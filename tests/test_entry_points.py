"""Every ``python -m`` entry point of the repository parses its arguments: ``--help`` prints
its usage, exits 0 and writes nothing into the source tree.

The modules are found by their ``if __name__ == "__main__":`` block. Writes are caught in the
child process itself by an audit hook (``sys.addaudithook``, loaded through a
``sitecustomize`` module on ``PYTHONPATH``) that logs every file it opens for writing, so files
other processes change in the tree meanwhile do not count; the results page and its figures
are also compared byte for byte before and after.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SOURCES = {
    "localpbo_core": ROOT,
    "localpbo_msgs_py": ROOT,
    "sims": ROOT,
    "localpbo_ros": ROOT / "ros_ws" / "src" / "localpbo_ros",
    "localpbo_examples": ROOT / "ros_ws" / "src" / "localpbo_examples",
}
HELP_DOMAIN_ID = 91
"""ROS domain of the node modules' ``--help`` runs (they must not start a node at all)."""

AUDIT = """
import os, sys
_log = os.environ["LOCALPBO_WRITE_LOG"]
_WRITE = os.O_WRONLY | os.O_RDWR | os.O_CREAT | os.O_APPEND | os.O_TRUNC

def _hook(event, args):
    if event != "open" or not args or not isinstance(args[0], (str, bytes, os.PathLike)):
        return
    path, mode, flags = args
    writes = (isinstance(mode, str) and any(c in mode for c in "wax+")) or (
        isinstance(flags, int) and flags & _WRITE
    )
    if writes and os.fsdecode(path) != _log:
        with open(_log, "a") as fh:
            fh.write(os.path.abspath(os.fsdecode(path)) + "\\n")

sys.addaudithook(_hook)
"""


def entry_modules() -> list[str]:
    """Dotted names of the modules with a ``__main__`` block (tests excluded)."""
    found = []
    for package, base in SOURCES.items():
        folder = base / package
        for path in sorted(folder.rglob("*.py")):
            if "__pycache__" in path.parts:
                continue
            if 'if __name__ == "__main__":' in path.read_text(errors="replace"):
                found.append(".".join(path.relative_to(base).with_suffix("").parts))
    return found


MODULES = entry_modules()


def test_the_entry_points_are_found() -> None:
    assert "localpbo_core.report" in MODULES and "localpbo_core.cli" in MODULES
    assert "localpbo_ros.sim_node" in MODULES
    assert not any(m.startswith("tests") for m in MODULES)


def _snapshot() -> dict[str, bytes]:
    files = [ROOT / "docs" / "RESULTS.md", *(ROOT / "docs" / "results" / "figures").glob("*")]
    return {str(p): p.read_bytes() for p in files}


@pytest.mark.parametrize("module", MODULES)
def test_help_prints_usage_and_writes_nothing(module: str, tmp_path: Path) -> None:
    (tmp_path / "sitecustomize.py").write_text(AUDIT)
    log = tmp_path / "writes.log"
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(tmp_path), env.get("PYTHONPATH", "")])
    env["LOCALPBO_WRITE_LOG"] = str(log)
    env["ROS_DOMAIN_ID"] = str(HELP_DOMAIN_ID)
    env["PYTHONDONTWRITEBYTECODE"] = "1"
    before = _snapshot()
    proc = subprocess.run(
        [sys.executable, "-m", module, "--help"],
        cwd=ROOT,
        env=env,
        capture_output=True,
        text=True,
        timeout=300,  # imports take long on a loaded machine
    )
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "usage:" in proc.stdout, proc.stdout + proc.stderr
    writes = log.read_text().splitlines() if log.exists() else []
    inside = [w for w in writes if Path(w).is_relative_to(ROOT)]
    assert inside == [], inside
    assert _snapshot() == before
