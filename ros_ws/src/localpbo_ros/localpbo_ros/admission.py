"""The ids a run's peers accept, derived from its run config.

Peers on a DDS domain are not authenticated (rclpy gives a subscription no publisher identity
per message), so a well-formed message with the right run id can come from anyone. What bounds
the damage is the run itself: budget counts evaluations (paper App. D.1) and every candidate
is evaluated once, so a run's candidates have ids ``0 .. budget - 1``, and every registered
algorithm asks at most one duel per evaluation (measured: all eight algorithms, budgets 12 and
24, ``duels <= budget - 1``). The default range is twice that (candidate ids below
``2 * budget``, duel ids below ``4 * budget``): ids are run-level and never reused, so work a
person's undo discards spends ids too. A run config may state other ranges in its optional
``ids`` section (``{"candidates": int, "duels": int}``, each >= 1).

Nodes check every id against these ranges before they store or evaluate anything, so a forged
message costs at most one stored entry (or one episode) per id of the run; everything outside
is dropped and counted (``dropped_id_out_of_range``).
"""

from __future__ import annotations

from dataclasses import dataclass

from localpbo_core.validation import SettingError
from localpbo_msgs_py import (
    CandidateMsg,
    DecodeError,
    DecodeReason,
    DuelOutcome,
    DuelRequest,
    EpisodeResult,
    Incumbent,
    RunConfig,
    Status,
    topics,
)
from localpbo_ros.base import NO_RUN

IDS_SECTION = "ids"
IDS_PER_EVALUATION = 2
"""Default candidate-id range per evaluation of the budget (see the module docstring)."""
DUELS_PER_CANDIDATE = 2
"""Default duel-id range per candidate id."""
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
    candidates = _count(ids, "candidates", IDS_PER_EVALUATION * config.budget)
    return IdRange(candidates, _count(ids, "duels", DUELS_PER_CANDIDATE * candidates))


BEFORE_RUN = "before_run"
"""Why a message is foreign while no run config is known."""
CONFLICTING_CONFIG = "conflicting_config"
"""Why a run config with the run's id but other content is foreign."""


class RunFilter:
    """Tells the messages of one run from foreign traffic (the recorder's triage).

    The run is the one of the first valid run config (or of ``run_id``). A message belongs to
    it when it decodes as its topic's schema with the run's id, its ids lie in the run's
    range and, for a candidate, θ has the run's dimension and lies in its box; a status when
    it carries the run's id or none yet (``none``: a node of the suite before it learns the
    run). Everything else is foreign, with the reason (a decode reason,
    ``id_out_of_range``, ``conflicting_config``, or ``before_run`` while no config is known).

    Args:
        run_id: the run to keep; empty = the first valid run config's.
    """

    def __init__(self, run_id: str = "") -> None:
        self.wanted = run_id or None
        self.config: RunConfig | None = None
        self.ids = IdRange(0, 0)

    def classify(self, topic: str, msg: object) -> str | None:
        """None for a message of the run on ``topic``; else why it is foreign."""
        if topic == topics.RUN_CONFIG.name:
            return self._config(msg)
        if topic == topics.STATUS.name:
            status = Status.decode(msg)
            if isinstance(status, DecodeError):
                return status.reason.value
            if status.run_id == NO_RUN:
                return None
            if self.config is None:
                return BEFORE_RUN
            return None if status.run_id == self.config.run_id else DecodeReason.WRONG_RUN.value
        config = self.config
        if config is None:
            return BEFORE_RUN
        run = config.run_id
        if topic == topics.CANDIDATE.name:
            cand = CandidateMsg.decode(
                msg,
                expected_run_id=run,
                expected_dim=config.dim,
                lower=config.lower,
                upper=config.upper,
            )
            return cand.reason.value if isinstance(cand, DecodeError) else self._candidates(cand)
        if topic == topics.INCUMBENT.name:
            inc = Incumbent.decode(msg, expected_run_id=run, expected_dim=config.dim)
            return inc.reason.value if isinstance(inc, DecodeError) else self._candidates(inc)
        if topic == topics.EPISODE_RESULT.name:
            res = EpisodeResult.decode(msg, expected_run_id=run)
            return res.reason.value if isinstance(res, DecodeError) else self._candidates(res)
        if topic in (topics.DUEL_REQUEST.name, topics.DUEL_OUTCOME.name):
            decoder = DuelRequest if topic == topics.DUEL_REQUEST.name else DuelOutcome
            duel = decoder.decode(msg, expected_run_id=run)
            if isinstance(duel, DecodeError):
                return duel.reason.value
            ok = self.ids.duel(duel.duel_id, duel.first_id, duel.second_id)
            return None if ok else OUT_OF_RANGE
        return DecodeReason.WRONG_TYPE.value

    def _config(self, msg: object) -> str | None:
        decoded = RunConfig.decode(msg, expected_run_id=self.wanted)
        if isinstance(decoded, DecodeError):
            return decoded.reason.value
        if self.config is None:
            try:
                self.ids = id_range(decoded)
            except SettingError:
                return DecodeReason.MALFORMED.value
            self.config = decoded
            return None
        if decoded.run_id != self.config.run_id:
            return DecodeReason.WRONG_RUN.value
        return None if decoded.to_json() == self.config.to_json() else CONFLICTING_CONFIG

    def _candidates(self, decoded: CandidateMsg | Incumbent | EpisodeResult) -> str | None:
        return None if self.ids.candidate(decoded.candidate_id) else OUT_OF_RANGE
