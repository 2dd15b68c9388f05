"""``make test`` runs on two xdist workers: every test file that starts processes, a browser or
Ray is in a group of ``tests/conftest.py``, and the groups that may run at the same time do
not share a ROS domain."""

from __future__ import annotations

import re
from pathlib import Path

from tests.conftest import GROUPS, TESTS, group_of

SHARED_HOST = re.compile(r"host_env|ROS_DOMAIN_ID|webdriver|localpbo_ros\.benchmarks|\bray\b")
"""What a test shares with the other tests on this host: DDS domains, a browser, Ray."""
STARTS_PROCESSES = re.compile(r"subprocess|Popen|sys\.executable")
"""Other processes: in a ROS test, node processes (plain Python processes elsewhere are
private to their test)."""
DOMAIN = re.compile(r"host_env\((\d+)(?: \+ seed)?\)|ROS_DOMAIN_ID\"\] = \"(\d+)\"|domain=(\d+)")


def shares_the_host(path: Path) -> bool:
    text = path.read_text()
    ros = path.parent.name == "ros"
    return bool(SHARED_HOST.search(text) or (ros and STARTS_PROCESSES.search(text)))


def test_every_file_that_starts_processes_is_in_a_group() -> None:
    loose = [
        p.relative_to(TESTS).as_posix()
        for p in sorted(TESTS.rglob("test_*.py"))
        if p.name != Path(__file__).name and shares_the_host(p) and group_of(p) is None
    ]
    assert loose == []


def test_grouped_files_exist() -> None:
    for files in GROUPS.values():
        for name in files:
            assert (TESTS / name).is_file(), name


def domains(group: str) -> set[int]:
    found: set[int] = set()
    for name in GROUPS[group]:
        text = (TESTS / name).read_text()
        for match in DOMAIN.finditer(text):
            base = int(next(g for g in match.groups() if g))
            # a "+ seed" domain covers the next few ids (seeds are below 5)
            found |= set(range(base, base + 5)) if "seed" in match.group(0) else {base}
    return found


def test_groups_running_side_by_side_use_different_ros_domains() -> None:
    stops, others = domains("ros-stops"), domains("ros")
    assert stops and others
    assert not stops & others, sorted(stops & others)


def test_the_stored_results_tests_read_each_run_once() -> None:
    """The files of the "stored-runs" group read the stored runs through the session's cache
    (fixture ``stored_runs_read_once``), so the group reads each run file once."""
    for name in GROUPS["stored-runs"]:
        text = (TESTS / name).read_text()
        assert 'pytestmark = pytest.mark.usefixtures("stored_runs_read_once")' in text, name
