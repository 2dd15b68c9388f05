"""Which tests may run side by side under ``pytest -n 2 --dist loadgroup`` (``make test``).

Tests that start node processes share fixed ROS domain ids and look at the processes and
sockets of this host; tests that start Ray share its session folder and ports; the tests of
the stored results read every stored run once per module. Each of those kinds runs in one
xdist group (one worker, one test at a time); every other test runs on whichever worker is
free. Without xdist (plain ``pytest``) the groups change nothing.
"""

from __future__ import annotations

from collections.abc import Iterator
from functools import cache
from pathlib import Path
from typing import Any

import pytest

TESTS = Path(__file__).resolve().parent

PROCESS_TESTS = tuple(
    f"ros/test_{name}.py"
    for name in (
        "bag_refusals",
        "bridge_exact",
        "bridge_pool",
        "bridge_processes",
        "colcon",
        "dds_scope",
        "episode_process",
        "hostile_processes",
        "judge_browser",
        "judge_resume",
        "multiprocess",
        "node_conventions",
        "params",
        "paths",
        "pool_processes",
        "resume",
        "signals",
    )
)
"""The ROS tests that start node processes or a browser (the others keep their nodes in the
test's process with discovery off, ``tests/ros/conftest.py``, and run beside anything)."""

GROUPS: dict[str, tuple[str, ...]] = {
    # node processes on ROS domains 64-74 (and the load they put on both cores)
    "ros-stops": ("ros/test_run_stops.py",),
    # node processes on the other fixed domains, the judge page in a browser, documented
    # commands, entry points
    "ros": (*PROCESS_TESTS, "test_entry_points.py", "test_docs_commands.py", "test_no_ros.py"),
    # an embedded or started Ray cluster
    "ray": ("test_sweep.py", "test_sweep_cluster.py"),
    # the stored runs, read once per worker (fixture ``stored_runs_read_once``)
    "stored-runs": ("test_notes_coverage.py", "test_results_page.py", "test_which_algorithm.py"),
}
"""xdist group name -> test files (relative to ``tests/``). Two groups may run at the same
time, so the ROS domains of "ros-stops" are used by no other test."""


def group_of(path: Path) -> str | None:
    """The group of the test file ``path``, or None when it may run beside any other."""
    relative = path.resolve().relative_to(TESTS).as_posix()
    return next((name for name, files in GROUPS.items() if relative in files), None)


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    for item in items:
        name = group_of(item.path)
        if name is not None:
            item.add_marker(pytest.mark.xdist_group(name))


@pytest.fixture(scope="session")
def stored_runs_read_once() -> Iterator[None]:
    """Read each stored run's file once per test process: the report's per-file reader
    (:func:`localpbo_core.report.read_stored_run`, a few hundred MB of JSON over all stored
    runs) is cached by the file's path, modification time and size, so a changed file is read
    again. The tests of the stored results share one xdist worker ("stored-runs")."""
    import localpbo_core.report as report

    read = report.read_stored_run

    @cache
    def cached(path: Path, _mtime_ns: int, _size: int) -> Any:
        run, code = read(path)
        for array in (run.best_seen, run.cumulative):
            array.setflags(write=False)  # shared by every reader: changing one fails
        return run, code

    def read_once(path: Path) -> Any:
        stat = path.stat()
        return cached(path.resolve(), stat.st_mtime_ns, stat.st_size)

    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(report, "read_stored_run", read_once)
        yield


@pytest.fixture(scope="module")
def tiny_spec() -> Any:
    """The bundled ``tiny`` spec: Sobol and TuRPBO on Hartmann 6, 8 evaluations, seeds 0-1."""
    from localpbo_core.experiments import load_spec

    return load_spec("tiny")


@pytest.fixture(scope="module")
def tiny_reference(tiny_spec: Any, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The uninterrupted in-process sweep of the ``tiny`` spec (no Ray): its 4 runs."""
    from localpbo_core.sweep import sweep

    out = tmp_path_factory.mktemp("reference")
    result = sweep(tiny_spec, out, in_process=True, progress=False)
    assert len(result.finished) == 4 and not result.failed
    return out
