"""The ids a run's peers accept, derived from its run config.

Peers on a DDS domain are not authenticated (rclpy gives a subscription no publisher identity
per message), so a well-formed message with the right run id can come from anyone. What bounds
the damage is the run itself: budget counts evaluations (paper App. D.1) and every candidate
is evaluated once, so the candidates of a run have ids ``0 .. budget - 1``; every registered
algorithm asks at most one duel per evaluation (measured: all eight algorithms, budgets 12 and
24, ``duels <= budget - 1``), so twice the candidate range is room enough for duel ids. A run
config may state other ranges in its optional ``ids`` section (``{"candidates": int,
"duels": int}``, each >= 1), e.g. for a protocol that spends ids on withdrawn work.

Nodes check every id against these ranges before they store or evaluate anything, so a forged
message costs at most one stored entry (or one episode) per id of the run; everything outside
is dropped and counted (``dropped_id_out_of_range``).
"""

from __future__ import annotations

from dataclasses import dataclass

from localpbo_core.validation import SettingError
from localpbo_msgs_py import RunConfig

IDS_SECTION = "ids"
DUELS_PER_CANDIDATE = 2
"""Default duel-id range per candidate id (see the module docstring)."""
OUT_OF_RANGE = "id_out_of_range"
"""Drop reason of a message whose id lies outside the run's range."""


@dataclass(frozen=True)
class IdRange:
    """Candidate ids ``0 .. candidates - 1`` and duel ids ``0 .. duels - 1`` of one run."""

    candidates: int
    duels: int

    def candidate(self, candidate_id: int) -> bool:
        """Whether ``candidate_id`` can be a candidate of the run."""
        return 0 <= candidate_id < self.candidates

    def duel(self, duel_id: int, first_id: int, second_id: int) -> bool:
        """Whether a duel ``duel_id`` between ``first_id`` and ``second_id`` can be one of the
        run's duels."""
        return 0 <= duel_id < self.duels and self.candidate(first_id) and self.candidate(second_id)


def _count(ids: dict[str, object], key: str, default: int) -> int:
    value = ids.get(key, default)
    if isinstance(value, bool) or not isinstance(value, int) or value < 1:
        raise SettingError(
            f"options.{IDS_SECTION}.{key}", f"must be an integer >= 1, got {value!r}"
        )
    return value


def id_range(config: RunConfig) -> IdRange:
    """The id range of the run ``config`` describes.

    Raises:
        SettingError: a malformed ``ids`` section (``options.ids.<key>`` named).
    """
    ids = config.options.get(IDS_SECTION, {})
    if not isinstance(ids, dict):
        raise SettingError(f"options.{IDS_SECTION}", "must be a JSON object")
    unknown = sorted(set(ids) - {"candidates", "duels"})
    if unknown:
        raise SettingError(f"options.{IDS_SECTION}.{unknown[0]}", "is not a known key")
    candidates = _count(ids, "candidates", config.budget)
    return IdRange(candidates, _count(ids, "duels", DUELS_PER_CANDIDATE * candidates))
