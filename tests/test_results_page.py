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
