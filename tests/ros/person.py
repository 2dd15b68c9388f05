"""A scripted person on the judge's page, over its HTTP API (what the page itself sends)."""

from __future__ import annotations

import json
import time
import urllib.error
import urllib.request
from typing import Any

POLL_S = 0.005


def get(url: str) -> Any:
    with urllib.request.urlopen(url, timeout=10) as r:
        return json.loads(r.read())


def post(url: str, body: dict[str, Any]) -> tuple[int, Any]:
    req = urllib.request.Request(url, data=json.dumps(body).encode())
    try:
        with urllib.request.urlopen(req, timeout=10) as r:
            return r.status, json.loads(r.read())
    except urllib.error.HTTPError as err:
        return err.code, json.loads(err.read() or b"{}")


def next_ready(url: str, after: int = -1, timeout_s: float = 120.0) -> dict[str, Any] | None:
    """The first ready duel other than ``after`` with id >= 0 (None once the run has ended);
    ``after`` = -1 takes any."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        state = get(url + "api/state")
        duel = state.get("duel")
        if duel is not None and duel["ready"] and duel["duel_id"] != after:
            return dict(duel)
        if duel is None and state.get("finished"):
            return None
        time.sleep(POLL_S)
    raise TimeoutError("no ready duel in time")


def answer(url: str, duel: dict[str, Any], choice: str) -> tuple[int, Any]:
    body = {
        "duel_id": duel["duel_id"],
        "first_id": duel["a"]["id"],
        "second_id": duel["b"]["id"],
        "choice": choice,
    }
    return post(url + "api/answer", body)


def undo(url: str, duel_id: int) -> tuple[int, Any]:
    return post(url + "api/undo", {"duel_id": duel_id})
