"""``python -m localpbo_core.experiments.drift``: where a re-run departs from a stored run."""

from __future__ import annotations

from localpbo_core.experiments.drift import compare, table
from localpbo_core.provenance import code_block


def _doc(natives: list[list[float]], final: float, code: dict | None = None) -> dict:
    doc = {
        "run": {"run_id": "hartmann6__hbei__seed1"},
        "settings": {"algorithm": "hbei"},
        "candidates": [{"id": i, "native": x, "value": 0.0} for i, x in enumerate(natives)],
        "records": [{"best_seen": final}],
    }
    if code is not None:
        doc["code"] = code
    return doc


def test_first_difference_and_finals() -> None:
    stored = _doc([[0.1, 0.2], [0.3, 0.4], [0.5, 0.6]], 2.966)
    now = _doc([[0.1, 0.2], [0.3, 0.4 + 1e-12], [0.9, 0.9]], 2.942)
    d = compare(stored, now)
    assert (d.identical, d.candidates, d.stored_final, d.now_final) == (1, 3, 2.966, 2.942)
    assert abs(d.first_gap - 1e-12) < 1e-15
    assert (d.stored_code, d.algorithm_changed) == ("none", "unknown")
    same = compare(stored, stored)
    assert (same.identical, same.first_gap) == (3, 0.0)
    assert table([d])[-1] == (
        "| hartmann6__hbei__seed1 | none | unknown | 1 of 3 | 1e-12 | 2.966 | 2.942 |"
    )


def test_stored_code_is_judged_against_today() -> None:
    today = dict(code_block("hbei"))
    older = {**today, "algorithm_digest": "0" * 16, "commit": "abcdef1234567", "dirty": True}
    x = [[0.5]]
    assert compare(_doc(x, 1.0, today), _doc(x, 1.0)).algorithm_changed == "no"
    changed = compare(_doc(x, 1.0, older), _doc(x, 1.0))
    assert (changed.stored_code, changed.algorithm_changed) == ("abcdef1234+dirty", "yes")
