"""``oracle_node``: answers duel requests from episode returns (paper Sec. 2, eqs. (2)-(3)).

Subscribes ``/localpbo/run_config``, ``/localpbo/episode_result``, ``/localpbo/duel_request``;
publishes ``/localpbo/duel_outcome`` and ``/localpbo/status``. Results and duels are matched by
id, never by arrival order; a request waits until both episode results are known.

The comparison is the run's simulated oracle, ``localpbo_core.problems.DuelOracle``: noise
std = ``noise_fraction`` × the task's value range (run config ``options.oracle``), drawn per
duel from ``localpbo_core.seeds.duel_seed(run seed, duel id)``. The answer to a duel is a
function of the run seed, the duel id and the two returns only, so duplicates, late joiners,
resumed runs and ``localpbo bench`` get the same answer. With the run config's
``oracle.indifference`` > 0 the oracle answers "can't tell" (an ``indifferent`` outcome) when
its noisy difference is below that fraction of the value range
(:meth:`~localpbo_core.problems.DuelOracle.judge`: the same per-duel draw as the core's
loop). An answer is stored and re-published for a repeated request. A failed episode result
fails the duels waiting on it (and is then forgotten, so a retry waits for the fresh result).

Bounded under forged traffic: results are kept only for candidate ids of the run's range,
answers only for its duel ids (:mod:`localpbo_ros.admission`), and at most ``max_pending``
duels wait for results; everything else is dropped and counted (``dropped_<reason>``).
"""

from __future__ import annotations

from typing import NoReturn, Unpack

from localpbo_core.problems import DuelOracle
from localpbo_msgs_py import DuelOutcome, DuelRequest, EpisodeResult, RunConfig
from localpbo_msgs_py.records import EpisodeStatus
from localpbo_msgs_py.topics import DUEL_OUTCOME, DUEL_REQUEST, EPISODE_RESULT
from localpbo_ros.base import NodeOptions
from localpbo_ros.driver import problem_of, settings_of
from localpbo_ros.follower import FollowerNode


def judge(
    oracle: DuelOracle, request: DuelRequest, value_first: float, value_second: float
) -> DuelOutcome:
    """The outcome of ``request``: decisive (paper eq. (3): first wins iff y_first > y_second)
    or, with the oracle's ``indifference`` > 0, "can't tell" when the noisy values are closer
    than that band."""
    first_wins = oracle.judge(request.duel_id, value_first, value_second)
    if first_wins is None:
        return DuelOutcome.indifferent(request)
    return DuelOutcome.decisive(request, request.first_id if first_wins else request.second_id)


class OracleNode(FollowerNode):
    """The preference-oracle node (see module docstring)."""

    def __init__(self, **options: Unpack[NodeOptions]) -> None:
        super().__init__("oracle_node", [], **options)
        self._oracle: DuelOracle | None = None
        self._results: dict[int, EpisodeResult] = {}
        self._waiting: dict[int, DuelRequest] = {}
        self._answered: dict[int, DuelOutcome] = {}
        self._pub = self.publisher(DUEL_OUTCOME)
        self.subscribe(EPISODE_RESULT, self._on_result)
        self.subscribe(DUEL_REQUEST, self._on_request)

    def episode_return(self, candidate_id: int) -> float | None:
        """The episode return received for a candidate (None if unknown or failed).

        For reports only (``localpbo run``'s summary); the optimizer never sees returns.
        """
        res = self._results.get(candidate_id)
        if res is None or res.episode_return is None:
            return None
        return float(res.episode_return)

    def reset(self) -> None:
        """Forget the previous run's results and duels."""
        self._results.clear()
        self._waiting.clear()
        self._answered.clear()

    def adopt(self, config: RunConfig) -> None:
        """Build the run's oracle (the task's value range scales the noise)."""
        settings = settings_of(config)
        self._oracle = DuelOracle(
            problem_of(config),
            settings.noise_fraction,
            settings.seed,
            indifference=settings.indifference,
        )

    # ------------------------------------------------------------------ callbacks
    def _on_result(self, msg: object) -> None:
        res = self.admitted(self._on_result, self.result, msg)
        if res is None:
            return
        known = self._results.get(res.candidate_id)
        if (
            res.status is EpisodeStatus.OK
            and known is not None
            and (known.status is EpisodeStatus.OK)
        ):
            if known.episode_return != res.episode_return:
                self.drop(
                    "conflicting_result",
                    f"candidate {res.candidate_id}: {res.episode_return} after "
                    f"{known.episode_return}",
                )
            else:
                self.counters["results_repeated"] += 1
            return
        self._results[res.candidate_id] = res
        self._resolve_waiting()

    def _on_request(self, msg: object) -> None:
        req = self.admitted(self._on_request, self.request, msg)
        if req is None:
            return
        done = self._answered.get(req.duel_id)
        if done is not None:
            if (done.first_id, done.second_id) != (req.first_id, req.second_id):
                self.drop("conflicting_request", f"duel {req.duel_id} changed its candidates")
            else:
                self.counters["outcomes_repeated"] += 1
                self._pub.publish(done.encode())
            return
        waiting = self._waiting.get(req.duel_id)
        if waiting is not None and waiting != req:
            self.drop("conflicting_request", f"duel {req.duel_id} changed its candidates")
            return
        if waiting is None and len(self._waiting) >= self.settings["max_pending"]:
            self.drop("buffer_full", f"more than {self.settings['max_pending']} duels waiting")
            return
        self._waiting[req.duel_id] = req
        self._resolve_waiting()

    # ------------------------------------------------------------------ matching
    def _resolve_waiting(self) -> None:
        assert self.config is not None
        consumed: set[int] = set()
        for duel_id in sorted(self._waiting):
            req = self._waiting[duel_id]
            first = self._results.get(req.first_id)
            second = self._results.get(req.second_id)
            failed = [
                r for r in (first, second) if r is not None and r.status is EpisodeStatus.FAILED
            ]
            if failed:
                reason = "; ".join(
                    f"episode of candidate {r.candidate_id} failed: {r.error}" for r in failed
                )[:4000]
                outcome = DuelOutcome.failed(req, reason)
                consumed.update(r.candidate_id for r in failed)
                self.counters["duels_failed"] += 1
            elif first is not None and second is not None:
                assert first.episode_return is not None and second.episode_return is not None
                assert self._oracle is not None
                outcome = judge(self._oracle, req, first.episode_return, second.episode_return)
                self._answered[duel_id] = outcome
                self.counters["duels_answered"] += 1
            else:
                continue
            del self._waiting[duel_id]
            self._pub.publish(outcome.encode())
        for cid in consumed:
            self._results.pop(cid, None)


def main(argv: list[str] | None = None) -> NoReturn:
    """``ros2 run localpbo_ros oracle_node [--ros-args -p run_id:=...]``."""
    from localpbo_ros.entry import run_node

    run_node(OracleNode, argv, stop_when_finished=False)


if __name__ == "__main__":
    main()
