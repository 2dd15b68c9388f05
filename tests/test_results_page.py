"""``docs/RESULTS.md`` is exactly what ``localpbo report`` makes of the committed results."""

from __future__ import annotations

from pathlib import Path

from localpbo_core.report import RESULTS_PAGE, write_results_page

ROOT = Path(__file__).resolve().parents[1]


def test_results_page_regenerates_byte_for_byte(tmp_path: Path) -> None:
    page = write_results_page(ROOT, tmp_path)
    committed = ROOT / RESULTS_PAGE["out"] / RESULTS_PAGE["name"]
    assert page.read_bytes() == committed.read_bytes(), (
        "docs/RESULTS.md is stale: run `python -m localpbo_core.report`"
    )
    figures = RESULTS_PAGE["figures"]
    made = sorted(p.name for p in (tmp_path / figures).iterdir())
    assert made == sorted(p.name for p in (ROOT / RESULTS_PAGE["out"] / figures).iterdir())


def test_readme_counts_the_claims_as_the_results_page_does() -> None:
    page = (ROOT / RESULTS_PAGE["out"] / RESULTS_PAGE["name"]).read_text()
    table = page.split("## The paper's claims", 1)[1].split("\n## ", 1)[0]
    rows = [line for line in table.splitlines() if line.startswith("| ")][2:]
    verdicts = [row.rstrip(" |").rsplit("| ", 1)[1].strip() for row in rows]
    counts = {v: verdicts.count(v) for v in ("yes", "partly", "no")}
    readme = " ".join((ROOT / "README.md").read_text().split())
    assert (
        f"Of the paper's {len(verdicts)} claims checked there, {counts['yes']} hold on our "
        f"runs, {counts['partly']} partly and {counts['no']} not" in readme
    ), counts
