"""``docs/RESULTS.md`` is exactly what the documented ``localpbo report`` command makes of the
committed results."""

from __future__ import annotations

import shlex
from pathlib import Path

import pytest

from localpbo_core.report import RESULTS_COMMAND, results_page_args, write_results_page

ROOT = Path(__file__).resolve().parents[1]

pytestmark = pytest.mark.usefixtures("stored_runs_read_once")


@pytest.fixture(scope="module")
def page() -> str:
    args = results_page_args(ROOT)
    return (Path(args.out) / args.name).read_text()


def test_reproducing_documents_the_command_the_page_is_made_with() -> None:
    text = " ".join((ROOT / "docs" / "reproducing.md").read_text().split())
    assert shlex.join(RESULTS_COMMAND) in text


def test_results_page_regenerates_byte_for_byte(tmp_path: Path) -> None:
    made = write_results_page(ROOT, tmp_path)
    args = results_page_args(ROOT)
    committed = Path(args.out) / args.name
    assert made.read_bytes() == committed.read_bytes(), (
        f"docs/RESULTS.md is stale: run `{shlex.join(RESULTS_COMMAND)}`"
    )
    ours = sorted(p.name for p in (tmp_path / args.figures).iterdir())
    assert ours == sorted(p.name for p in (Path(args.out) / args.figures).iterdir())
    for name in ours:
        assert (tmp_path / args.figures / name).read_bytes() == (
            Path(args.out) / args.figures / name
        ).read_bytes(), name


def test_readme_counts_the_claims_as_the_results_page_does(page: str) -> None:
    table = page.split("## The paper's claims", 1)[1].split("\n## ", 1)[0]
    rows = [line for line in table.splitlines() if line.startswith("| ")][2:]
    verdicts = [row.rstrip(" |").rsplit("| ", 1)[1].strip() for row in rows]
    counts = {v: verdicts.count(v) for v in ("yes", "partly", "no", "not run")}
    readme = " ".join((ROOT / "README.md").read_text().split())
    verb = "is" if counts["not run"] == 1 else "are"
    assert (
        f"Of the paper's {len(verdicts)} claims checked there, {counts['yes']} hold on our "
        f"runs, {counts['partly']} partly, {counts['no']} not, and {counts['not run']} {verb} "
        "not run yet" in readme
    ), counts
