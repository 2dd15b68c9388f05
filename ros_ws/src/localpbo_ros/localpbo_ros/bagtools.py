"""Reading a recorded run back from its bag (for ``replay --verify`` and ``run --resume``)."""

from __future__ import annotations

import os
from dataclasses import dataclass

from localpbo_msgs_py import CandidateMsg, DuelOutcome, DuelRequest, RunConfig
from localpbo_msgs_py.bag import BagWriter, read_messages, summarize
from localpbo_msgs_py.topics import ALL_TOPICS, CANDIDATE, DUEL_OUTCOME, DUEL_REQUEST, RUN_CONFIG


@dataclass(frozen=True)
class RecordedRun:
    """What a bag says about one run.

    Attributes:
        config: the run config (the file alone says how the run was made).
        candidates: first recorded message of each candidate id.
        requests: first recorded request of each duel id.
        outcomes: every decodable outcome of this run, in recorded order (the optimizer's
            acceptance rule is applied when they are re-fed, see ``driver.rebuild``).
        complete: the file has its footer (the recorder was closed, not killed).
    """

    config: RunConfig
    candidates: dict[int, CandidateMsg]
    requests: dict[int, DuelRequest]
    outcomes: tuple[DuelOutcome, ...]
    complete: bool


def load_run(path: str | os.PathLike[str]) -> RecordedRun:
    """Decode the run recorded in ``path`` (finished or cut off by a crash).

    Raises:
        ValueError: no valid run config, or configs of two different runs in one bag.
    """
    config: RunConfig | None = None
    for rec in read_messages(path, topics=[RUN_CONFIG.name]):
        decoded = RunConfig.decode(rec.message)
        if not isinstance(decoded, RunConfig):
            continue
        if config is None:
            config = decoded
        elif decoded.to_json() != config.to_json():
            raise ValueError(
                f"{path}: holds run configs of two runs ({config.run_id!r}, {decoded.run_id!r})"
            )
    if config is None:
        raise ValueError(f"{path}: no valid {RUN_CONFIG.name} message; not a localpbo run bag")
    candidates: dict[int, CandidateMsg] = {}
    requests: dict[int, DuelRequest] = {}
    outcomes: list[DuelOutcome] = []
    wanted = [CANDIDATE.name, DUEL_REQUEST.name, DUEL_OUTCOME.name]
    for rec in read_messages(path, topics=wanted):
        if rec.topic == CANDIDATE.name:
            cand = CandidateMsg.decode(
                rec.message, expected_run_id=config.run_id, expected_dim=config.dim
            )
            if isinstance(cand, CandidateMsg):
                candidates.setdefault(cand.candidate_id, cand)
        elif rec.topic == DUEL_REQUEST.name:
            req = DuelRequest.decode(rec.message, expected_run_id=config.run_id)
            if isinstance(req, DuelRequest):
                requests.setdefault(req.duel_id, req)
        else:
            out = DuelOutcome.decode(rec.message, expected_run_id=config.run_id)
            if isinstance(out, DuelOutcome):
                outcomes.append(out)
    return RecordedRun(config, candidates, requests, tuple(outcomes), summarize(path).complete)


def copy_into(path: str | os.PathLike[str], writer: BagWriter) -> int:
    """Append every message of ``path`` to ``writer`` with its original times; returns count."""
    writer.add_suite_topics(ALL_TOPICS)
    n = 0
    for rec in read_messages(path):
        writer.write(
            rec.topic, rec.message, log_time_ns=rec.log_time_ns, publish_time_ns=rec.publish_time_ns
        )
        n += 1
    return n
