"""A run of the suite with a judge (``run_suite(..., judge=...)``) in a thread, for tests that
play the person on its page."""

from __future__ import annotations

import threading
import time
from collections.abc import Iterable
from pathlib import Path
from typing import Any

from localpbo_ros.suite import run_suite

from localpbo_msgs_py import DuelOutcome


class JudgedSuite:
    """``run_suite(settings, bag, judge=judge, **options)`` in a daemon thread; ``url`` is the
    page's address once it is served (within ``url_timeout_s``)."""

    def __init__(
        self,
        settings: dict[str, Any],
        bag: Path,
        judge: dict[str, Any],
        url_timeout_s: float = 20.0,
        **options: Any,
    ) -> None:
        self.bag = bag
        self.urls: list[str] = []
        self.result: dict[str, Any] = {}

        def go() -> None:
            try:
                self.result["summary"] = run_suite(
                    settings, bag, judge=judge, on_url=self.urls.append, **options
                )
            except BaseException as exc:  # reported by finish()
                self.result["error"] = exc

        self.thread = threading.Thread(target=go, daemon=True)
        self.thread.start()
        deadline = time.monotonic() + url_timeout_s
        while not self.urls and self.thread.is_alive() and time.monotonic() < deadline:
            time.sleep(0.01)
        assert self.urls, self.result
        self.url = self.urls[0]

    def finish(self, timeout_s: float = 60.0) -> Any:
        """The run's summary, once it has ended (within ``timeout_s``) without an error."""
        self.thread.join(timeout_s)
        assert not self.thread.is_alive()
        assert "error" not in self.result, self.result["error"]
        return self.result["summary"]


def answers_once_each(outcomes: Iterable[DuelOutcome]) -> dict[int, DuelOutcome]:
    """The recorded outcomes of a person-judged run by duel id, each duel's first one.

    The bag holds every outcome published, and the judge sends a journaled answer again when
    the optimizer's request for it comes back (a request re-published before the answer was
    taken, likely on a loaded machine); the optimizer counts such a repeat as a duplicate.
    So a duel may be recorded more than once, but only ever with the same answer: anything
    else fails here."""
    first: dict[int, DuelOutcome] = {}
    for out in outcomes:
        assert first.setdefault(out.duel_id, out) == out, (first[out.duel_id], out)
    return first
