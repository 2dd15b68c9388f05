"""Run-config following for the simulator and oracle nodes.

They take everything about the run (task, its options, seed, noise) from the latched
``/localpbo/run_config`` the optimizer publishes. With parameter ``run_id`` empty they serve
the latest run whose config they received (a config with a new run id switches them over and
clears their state); otherwise only that run's. Messages that arrive before the config are
kept (at most ``max_pending``) and handled once it is known.

Ids are checked against the run's range (:mod:`localpbo_ros.admission`: candidates
``0 .. budget - 1`` unless the config says otherwise) before anything is stored or
evaluated; a message outside it is dropped and counted (``dropped_id_out_of_range``).
"""

from __future__ import annotations

import abc
from collections.abc import Callable
from typing import Any, TypeVar, Unpack

from localpbo_msgs_py import CandidateMsg, DecodeError, DuelRequest, EpisodeResult, RunConfig
from localpbo_msgs_py.topics import RUN_CONFIG
from localpbo_ros.admission import OUT_OF_RANGE, IdRange, id_range
from localpbo_ros.base import NodeOptions, SuiteNode
from localpbo_ros.params import Param

Decoded = TypeVar("Decoded")

FOLLOWER_PARAMS = [
    Param(
        "run_id",
        "",
        "Only serve this run; empty = the latest run config received (a new run id switches over).",
    ),
    Param(
        "max_pending",
        1000,
        "Messages kept while waiting for the run config; duels kept while waiting for "
        "episode results; candidates queued for evaluation.",
        int_range=(1, 1_000_000),
    ),
]


class FollowerNode(SuiteNode, abc.ABC):
    """A node that serves one run described by the latched run config."""

    def __init__(self, name: str, params: list[Param], **options: Unpack[NodeOptions]) -> None:
        super().__init__(name, FOLLOWER_PARAMS + params, **options)
        self.config: RunConfig | None = None
        self.ids = IdRange(0, 0)
        self._early: list[tuple[Callable[[Any], None], Any]] = []
        self.subscribe(RUN_CONFIG, self._on_config)
        self.state = "waiting"

    @property
    def run_id(self) -> str | None:
        """The served run, once known."""
        return None if self.config is None else self.config.run_id

    def _on_config(self, msg: object) -> None:
        wanted = self.settings["run_id"] or None
        decoded = RunConfig.decode(msg, expected_run_id=wanted)
        if isinstance(decoded, DecodeError):
            self.drop_decode(decoded)
            return
        if self.config is not None:
            if decoded.run_id == self.config.run_id:
                if decoded.to_json() != self.config.to_json():
                    self.drop(
                        "conflicting_config", f"run {decoded.run_id!r} already has another config"
                    )
                return
            self.get_logger().info(
                f"switching from run {self.config.run_id!r} to {decoded.run_id!r}"
            )
            self.config = None
            self.reset()
        try:
            ids = id_range(decoded)
            self.adopt(decoded)
        except Exception as exc:  # the config names a task or option this node cannot build
            self.state = "failed"
            self.get_logger().error(f"cannot serve run {decoded.run_id!r}: {exc}")
            self.publish_status(2, str(exc))
            return
        self.config = decoded
        self.ids = ids
        self.status_run_id = decoded.run_id
        self.state = "running"
        early, self._early = self._early, []
        for handler, held in early:
            handler(held)

    @abc.abstractmethod
    def reset(self) -> None:
        """Forget everything about the previous run."""

    @abc.abstractmethod
    def adopt(self, config: RunConfig) -> None:
        """Prepare for ``config`` (build the task); raise if impossible."""

    def hold(self, handler: Callable[[Any], None], msg: object) -> bool:
        """Keep ``msg`` for ``handler`` until the config arrives; True if it was held."""
        if self.config is not None:
            return False
        if len(self._early) >= self.settings["max_pending"]:
            self.drop("buffer_full", "message before run config, buffer full")
        else:
            self._early.append((handler, msg))
        return True

    def admitted(
        self,
        handler: Callable[[Any], None],
        decode: Callable[[object], Decoded | None],
        msg: object,
    ) -> Decoded | None:
        """``decode(msg)`` (e.g. :meth:`result`) once the run config is known; None while
        ``msg`` is held for ``handler`` (:meth:`hold`) or when ``decode`` dropped it."""
        if self.hold(handler, msg):
            return None
        return decode(msg)

    def candidate(self, msg: object) -> CandidateMsg | None:
        """Decode a candidate of the served run; None for a malformed one (dropped and counted
        by its decode reason). Call only once the run config is known (after :meth:`hold`)."""
        config = self.config
        assert config is not None
        cand = CandidateMsg.decode(
            msg,
            expected_run_id=config.run_id,
            expected_dim=config.dim,
            lower=config.lower,
            upper=config.upper,
        )
        if isinstance(cand, DecodeError):
            self.drop_decode(cand)
            return None
        if not self.ids.candidate(cand.candidate_id):
            self.drop(
                OUT_OF_RANGE, f"candidate {cand.candidate_id} (run has {self.ids.candidates})"
            )
            return None
        return cand

    def candidate_for(self, msg: object, worker_id: str) -> CandidateMsg | None:
        """:meth:`candidate` for the worker ``worker_id`` of a pool: also None for one
        assigned to another worker (counted as ``candidates_for_others``)."""
        cand = self.candidate(msg)
        if cand is not None and cand.worker and cand.worker != worker_id:
            self.counters["candidates_for_others"] += 1
            return None
        return cand

    def result(self, msg: object) -> EpisodeResult | None:
        """Decode an episode result of the served run for one of its candidates; None (dropped
        and counted) otherwise. Call only once the run config is known."""
        assert self.config is not None
        res = EpisodeResult.decode(msg, expected_run_id=self.config.run_id)
        if isinstance(res, DecodeError):
            self.drop_decode(res)
            return None
        if not self.ids.candidate(res.candidate_id):
            self.drop(OUT_OF_RANGE, f"result of candidate {res.candidate_id}")
            return None
        return res

    def request(self, msg: object) -> DuelRequest | None:
        """Decode a duel request of the served run within its id range; None (dropped and
        counted) otherwise. Call only once the run config is known."""
        assert self.config is not None
        req = DuelRequest.decode(msg, expected_run_id=self.config.run_id)
        if isinstance(req, DecodeError):
            self.drop_decode(req)
            return None
        if not self.ids.duel(req.duel_id, req.first_id, req.second_id):
            self.drop(OUT_OF_RANGE, f"duel {req.duel_id} ({req.first_id} vs {req.second_id})")
            return None
        return req
