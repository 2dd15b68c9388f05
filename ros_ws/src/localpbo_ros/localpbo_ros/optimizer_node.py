"""``optimizer_node``: owns the ask/tell optimizer; publishes candidates and duel requests.

Topics: publishes ``/localpbo/run_config`` (latched), ``/localpbo/candidate``,
``/localpbo/duel_request``, ``/localpbo/incumbent`` (latched), ``/localpbo/status``;
subscribes ``/localpbo/duel_outcome``. The algorithm lives in ``localpbo_core``; the
bookkeeping in :class:`localpbo_ros.driver.Driver`.

Failure policy (parameter ``failure_policy``): a duel whose outcome is ``failed`` (the
simulator raised, the oracle lacked a result) or that has no outcome within ``duel_timeout_s``
is either retried (``retry``: the duel's candidates and request are published again, at most
``max_retries`` times per duel; the simulator re-runs failed episodes, the oracle answers
anew) or ends the run (``stop``, and ``retry`` once the retries are spent): the node goes to
state ``failed``, reports the reason on the status topic and stops publishing work. The
optimizer never sees a failed duel.

Speculation (parameter ``speculate``, for a person answering): while the last duel of an ask
is pending, the next ask is prepared for each of its possible answers in a background thread
(:meth:`localpbo_ros.driver.Driver.speculate`; it starts once the duel's episode results
are heard, or ``SPECULATE_WAIT_S`` after the request), so the next duel goes out as soon as the
answer arrives; what is asked is the same either way. Every duel request carries
``decision_seconds``: the time from the answer that completed the previous ask to the request
(``localpbo bag-info`` summarises them). Counter: ``speculated`` (answers whose next ask was
ready). Each prepared branch's new candidates go out on ``/localpbo/speculative_candidate``
(not recorded), so an evaluator runs their episodes ahead and answers the real candidate at
once (:mod:`localpbo_ros.sim_node`); the bag is the same with or without. The speculation
also computes the current recommendation (highest posterior mean
utility), announced as ``info.recommended`` in the node's status for the judge's page.

Undo (a person's): a ``retracted`` outcome takes back the latest accepted answer (up to
``UNDO_DEPTH`` answers back, one at a time; :meth:`localpbo_ros.driver.Driver.retract`). The
node then publishes that duel's request again under the same id (with its candidates) and
drops the duels it had asked since (answers to them are dropped as ``withdrawn``; their ids
are never reused). Counters: ``retractions``, and ``retraction_refused`` (with the reason in
the log) for one it cannot honour.

Late joiners: while a step is open, the pending duels' candidates and requests are published
again every ``republish_period_s`` (idempotent for the other nodes).

Pool of evaluators (:mod:`localpbo_ros.pool`): the node hears the workers' status heartbeats
(``info.worker``) of its run and assigns each candidate to evaluate to one live worker with
room (at most ``worker_queue`` candidates out per worker; ``worker=<id>`` in the candidate
message), the next one as soon as an episode result frees a place; a candidate whose worker
is silent for ``worker_timeout_s`` goes to another worker.
With no worker heard, candidates go out unassigned (anyone evaluates them). ``min_workers``
holds the start until that many workers are heard. Counters: ``assigned``, ``reassigned``,
``workers`` (live now).
"""

from __future__ import annotations

import json
import time
from collections.abc import Sequence
from typing import Any, NoReturn, Unpack

from localpbo_core.optimizers import available_optimizers
from localpbo_core.presets import available_presets
from localpbo_core.problems import available_problems
from localpbo_core.session import Reason
from localpbo_core.settings import (
    DEFAULT_ALGORITHM,
    DEFAULT_INITIAL_DESIGN,
    DEFAULT_NOISE_FRACTION,
    DEFAULT_PROBLEM,
    RunSettings,
    SettingError,
)
from localpbo_core.space import load_space
from localpbo_core.speculation import Branch
from localpbo_msgs_py import (
    CandidateMsg,
    DecodeError,
    DuelOutcome,
    DuelRequest,
    EpisodeResult,
    EpisodeStatus,
    RunConfig,
    Status,
    topics,
)
from localpbo_msgs_py.records import OutcomeKind
from localpbo_ros.base import NodeOptions, SuiteNode
from localpbo_ros.completeness import Published
from localpbo_ros.driver import (
    DEFAULT_FAILURE_POLICY,
    DEFAULT_MAX_RETRIES,
    FAILURE_POLICIES,
    Driver,
    judged_by_person,
    make_run_config,
    rebuild,
    settings_of,
    space_of,
)
from localpbo_ros.params import INT_MAX, Param, ParameterError
from localpbo_ros.pool import SERVING_STATES, WorkerPool, worker_of
from localpbo_ros.summary import RunSummary

PARAMS = [
    Param("run_id", "localpbo", "Run id stamped on every message ([A-Za-z0-9][A-Za-z0-9_.-]*)."),
    Param(
        "algorithm",
        DEFAULT_ALGORITHM,
        "Preference optimizer, or a preset (an algorithm with options, localpbo_core/presets.py; "
        "recorded as that algorithm with its options).",
        choices=(*available_optimizers(), *available_presets()),
    ),
    Param(
        "algorithm_options",
        "{}",
        'Algorithm options as a JSON object, e.g. {"batch_size": 2}.',
        json_object=True,
    ),
    Param("task", DEFAULT_PROBLEM, "Task (problem) to tune.", choices=tuple(available_problems())),
    Param(
        "task_options",
        "{}",
        'Task options as a JSON object, e.g. {"episode_steps": 200}.',
        json_object=True,
    ),
    Param(
        "space",
        "",
        "Parameter space file (YAML) to tune instead of task, or the space inline as JSON; "
        "candidates are then the space's parameters in their units.",
    ),
    Param(
        "budget",
        0,
        "Evaluations incl. the initial design; 0 = initial design + 10 d (paper App. D.1).",
        int_range=(0, 100_000),
    ),
    Param(
        "initial_design",
        DEFAULT_INITIAL_DESIGN,
        "Shared random initial points (paper App. D.1).",
        int_range=(2, 100_000),
    ),
    Param("seed", 0, "Run seed (optimizer, episode seeds, oracle noise).", int_range=(0, INT_MAX)),
    Param(
        "noise_fraction",
        DEFAULT_NOISE_FRACTION,
        "Oracle noise std as a fraction of the task's value range.",
        float_range=(0.0, 10.0),
    ),
    Param(
        "tie_threshold",
        0.0,
        "Indifference threshold eps of the ordinal likelihood (latent units); 'can't tell' "
        "outcomes are accepted iff > 0 (0 = the paper's model; 0.25 for a person judging).",
        float_range=(0.0, 10.0),
    ),
    Param(
        "indifference",
        0.0,
        "The simulated oracle answers 'can't tell' when its noisy difference is below this "
        "fraction of the task's value range (needs tie_threshold > 0; 0 = never).",
        float_range=(0.0, 10.0),
    ),
    Param(
        "oracle",
        "simulated",
        "Who answers the duels; 'human' is recorded in the run config (oracle.kind person), "
        "so a resume continues with a person.",
        choices=("simulated", "human"),
    ),
    Param(
        "failure_policy",
        DEFAULT_FAILURE_POLICY,
        "What a failed or timed-out duel does.",
        choices=FAILURE_POLICIES,
    ),
    Param(
        "max_retries",
        DEFAULT_MAX_RETRIES,
        "Retries per duel under failure_policy=retry.",
        int_range=(0, 100),
    ),
    Param(
        "progress_every",
        10,
        "Log progress at INFO every this many accepted duels (0 = never).",
        int_range=(0, 1_000_000),
    ),
    Param(
        "duel_timeout_s",
        120.0,
        "Seconds without progress before pending duels time out.",
        float_range=(0.05, 86_400.0),
    ),
    Param(
        "republish_period_s",
        2.0,
        "Re-publish pending work this often (late joiners).",
        float_range=(0.01, 3600.0),
    ),
    Param(
        "min_subscribers",
        1,
        "Start once candidate and duel_request topics have this many subscribers (what the "
        "start waits for is logged every few seconds).",
        int_range=(0, 1000),
    ),
    Param(
        "worker_timeout_s",
        30.0,
        "Seconds without a heartbeat before a worker's candidate goes to another worker "
        "(longer than the longest episode).",
        float_range=(0.5, 86_400.0),
    ),
    Param(
        "worker_queue",
        2,
        "Candidates out to one pool worker at a time (1 = the next one only after a result).",
        int_range=(1, 1000),
    ),
    Param(
        "speculate",
        False,
        "Prepare the next ask for every possible answer of the last pending duel while it is "
        "judged (for a person answering; costs one decision per possible answer).",
    ),
    Param(
        "min_workers",
        0,
        "Start once this many pool workers are heard (0 = do not wait).",
        int_range=(0, 1000),
    ),
]

TICK_S = 0.05
"""Period of the start / timeout / re-publish check."""
SPECULATE_WAIT_S = 1.0
"""Speculation starts when the open duel's episode results are in, or this long after."""
WAIT_NOTE_S = 1.0
"""Seconds of waiting for subscribers/workers before the optimizer says what it waits for."""

PARAMETER_OF_SETTING = {
    "algorithm": "algorithm",
    "problem": "task",
    "seed": "seed",
    "budget": "budget",
    "initial_design": "initial_design",
    "noise_fraction": "noise_fraction",
    "tie_threshold": "tie_threshold",
    "indifference": "indifference",
    "optimizer_options": "algorithm_options",
    "problem_options": "task_options",
    "failure_policy": "failure_policy",
    "max_retries": "max_retries",
    "run_id": "run_id",
    "space": "space",
}
"""The ROS parameter that sets each run setting (``SettingError.field`` up to its first dot)."""


def config_from_settings(s: dict[str, Any]) -> RunConfig:
    """The run config the parameters describe; ParameterError names the bad parameter."""
    try:
        space = load_space(s["space"]) if s["space"] else None
        settings = RunSettings(
            algorithm=s["algorithm"],
            problem=s["task"],
            seed=s["seed"],
            budget=s["budget"] or None,
            initial_design=s["initial_design"],
            noise_fraction=s["noise_fraction"],
            tie_threshold=s["tie_threshold"],
            indifference=s["indifference"],
            optimizer_options=s["algorithm_options"],
            problem_options=s["task_options"],
        )
        return make_run_config(
            s["run_id"],
            settings,
            failure_policy=s["failure_policy"],
            max_retries=s["max_retries"],
            space=space,
            person=s["oracle"] == "human",
        )
    except SettingError as exc:
        name = PARAMETER_OF_SETTING.get(exc.field.split(".", 1)[0], "algorithm_options")
        raise ParameterError(name, f"{exc.field}: {exc.reason}") from None
    except ValueError as exc:  # the run config codec refuses a field (e.g. the run id)
        field = getattr(exc, "field", "")
        raise ParameterError(PARAMETER_OF_SETTING.get(field, "run_id"), str(exc)) from None


def settings_from_config(config: RunConfig) -> dict[str, Any]:
    """Parameter values that reproduce ``config`` (used by ``run --resume``)."""
    settings = settings_of(config)
    failure = config.options.get("failure", {})
    space = space_of(config)
    extra: dict[str, Any] = {}
    if space is not None:  # the recorded space inline; its warm start is already an option
        extra = {"space": json.dumps(space.to_dict()), "task": DEFAULT_PROBLEM}
    return {
        "run_id": config.run_id,
        "algorithm": settings.algorithm,
        "algorithm_options": json.dumps(dict(settings.optimizer_options)),
        "task": settings.problem,
        "task_options": json.dumps(dict(settings.problem_options)),
        "budget": config.budget,
        "initial_design": settings.initial_design,
        "seed": settings.seed,
        "noise_fraction": float(settings.noise_fraction),
        "tie_threshold": float(settings.tie_threshold),
        "indifference": float(settings.indifference),
        "failure_policy": failure.get("policy", DEFAULT_FAILURE_POLICY),
        "max_retries": int(failure.get("max_retries", DEFAULT_MAX_RETRIES)),
        "oracle": "human" if judged_by_person(config) else "simulated",
        **extra,
    }


class OptimizerNode(SuiteNode):
    """The optimizer node (see module docstring).

    Args:
        context: rclpy context.
        overrides: parameter values.
        cli_args: ROS arguments.
        resume_outcomes: recorded duel outcomes to re-feed before starting (``run --resume``);
            the rebuilt run continues with the first unanswered duel.
    """

    def __init__(
        self,
        *,
        resume_outcomes: Sequence[DuelOutcome] = (),
        **options: Unpack[NodeOptions],
    ) -> None:
        super().__init__("optimizer_node", PARAMS, **options)
        self.config = config_from_settings(self.settings)
        self.status_run_id = self.config.run_id
        if resume_outcomes:
            self.driver: Driver = rebuild(self.config, resume_outcomes).driver
        else:
            self.driver = Driver(self.config)
        self.resumed_duels = self.driver.n_duels
        self.counters["duels_done"] = self.driver.n_duels  # a resumed run counts its history
        self.finished = False
        self.error = ""
        self._attempts: dict[int, int] = {}
        self._deadline = float("inf")
        self._last_publish = 0.0
        self._started = False
        self._waiting_since = time.monotonic()
        self._decision_s: dict[int, float] = {}  # duel id -> decision time of its ask
        self.published = Published()  # ids sent, in the status: verify finds a bag's gaps
        self._answered_at = 0.0  # when the answer that completed the last ask arrived
        self._evaluated: set[int] = set()  # candidates whose episode result was heard
        self._speculate_due: float | None = None  # speculate at the latest then
        self._cpu0 = 0.0
        self.started_at = 0.0
        self.finished_at = 0.0
        self.cpu_seconds = 0.0  # process CPU time from start to finish (benchmark)
        self._pub_config = self.publisher(topics.RUN_CONFIG)
        self._pub_candidate = self.publisher(topics.CANDIDATE)
        self._pub_request = self.publisher(topics.DUEL_REQUEST)
        self._pub_incumbent = self.publisher(topics.INCUMBENT)
        self._pub_ahead = self.publisher(topics.SPECULATIVE_CANDIDATE)
        self.pool = WorkerPool(self.settings["worker_timeout_s"], self.settings["worker_queue"])
        self.subscribe(topics.DUEL_OUTCOME, self._on_outcome)
        self.subscribe(topics.STATUS, self._on_status)
        self.subscribe(topics.EPISODE_RESULT, self._on_result)
        self._pub_config.publish(self.config.encode())
        self.state = "waiting"
        self._timer = self.create_timer(TICK_S, self._tick)

    def status_info(self) -> dict[str, str]:
        """``info.recommended``: the candidate with the highest posterior mean utility, once a
        speculation has computed it (runs with ``speculate``: a person is judging); and the
        ids published so far (``info.published_candidates``, ``info.published_duels``)."""
        rec = self.driver.prepared_recommendation()
        info = self.published.info()
        return info if rec is None else {**info, "recommended": str(rec.candidate_id)}

    # ------------------------------------------------------------------ timing
    def _now(self) -> float:
        return time.monotonic()

    def _tick(self) -> None:
        if self.finished:
            return
        now = self._now()
        if not self._started:
            need = self.settings["min_subscribers"]
            seen = (
                self._pub_candidate.get_subscription_count(),
                self._pub_request.get_subscription_count(),
                len(self.pool.live(now)),
            )
            if seen[0] >= need and seen[1] >= need and seen[2] >= self.settings["min_workers"]:
                self._start()
            elif now - self._waiting_since >= WAIT_NOTE_S:
                self._note_waiting(*seen)
            return
        self._maybe_speculate()
        if self.pool.outstanding() and any(
            w not in self.pool.live(now) for w in self.pool.outstanding().values()
        ):
            self._dispatch()
        if self.driver.step_open and now >= self._deadline:
            timeout = self.settings["duel_timeout_s"]
            for req in self.driver.pending_requests():
                self._failure(req.duel_id, f"timeout: no outcome within {timeout} s")
                if self.finished:
                    return
        elif (
            self.driver.step_open
            and now - self._last_publish >= self.settings["republish_period_s"]
        ):
            self._publish_pending()

    def _note_waiting(self, candidates: int, requests: int, workers: int) -> None:
        """Say (INFO, at most once per ``warn_period_s``) what the start waits for."""
        if self.warnings.admit("waiting_to_start") is None:
            return
        need = self.settings["min_subscribers"]
        text = (
            f"waiting to start: {topics.CANDIDATE.name} has {candidates} of {need} subscribers, "
            f"{topics.DUEL_REQUEST.name} {requests} of {need} (min_subscribers)"
        )
        if self.settings["min_workers"]:
            text += (
                f"; {workers} of {self.settings['min_workers']} pool workers heard (min_workers)"
            )
        self.get_logger().info(text)

    def _start(self) -> None:
        self._started = True
        self.started_at = self._now()
        self._answered_at = self.started_at
        self._cpu0 = time.process_time()
        self.state = "running"
        if self.driver.done:
            self._finish()
        elif self.driver.step_open:  # resumed in the middle of a step
            self._publish_incumbent()
            self._publish_pending()
            self._deadline = self._now() + self.settings["duel_timeout_s"]
            self._speculate_soon()
        else:
            self._next_step()

    # ------------------------------------------------------------------ publishing
    def _next_step(self) -> None:
        work = self.driver.ask()
        self._dispatch(fresh={c.candidate_id for c in work.candidates})
        decided = self._now() - self._answered_at
        for req in work.requests:
            self._decision_s[req.duel_id] = decided
            self._publish_request(req)
        self._last_publish = self._now()
        self._deadline = self._last_publish + self.settings["duel_timeout_s"]
        self._speculate_soon()

    def _speculate_soon(self) -> None:
        """Speculate once the open duel's episode results are in, or ``SPECULATE_WAIT_S``
        after the request: an episode that was not run ahead then runs without a decision
        competing for the interpreter, and the person's watching time is the speculation's."""
        if not self.settings["speculate"]:
            return
        self._speculate_due = self._now() + SPECULATE_WAIT_S
        self._maybe_speculate()

    def _maybe_speculate(self) -> None:
        due = self._speculate_due
        if due is None or self.finished:
            return
        pending = {c.candidate_id for c in self.driver.pending_candidates()}
        if pending <= self._evaluated or self._now() >= due:
            self._speculate_due = None
            self._speculate()

    def _speculate(self) -> None:
        if self.settings["speculate"] and self.driver.speculate(self._ahead) is not None:
            self.counters["speculations"] += 1

    def _ahead(self, branch: Branch) -> None:
        """A prepared branch (speculation thread): its new candidates go out on the
        unrecorded speculative topic, so their episodes run while the person judges."""
        for cand in self.driver.branch_candidates(branch):
            self._pub_ahead.publish(cand.encode())
            self.counters["candidates_ahead"] += 1

    def _publish_request(self, req: DuelRequest) -> None:
        timed = req.with_decision_seconds(self._decision_s.get(req.duel_id))
        self._pub_request.publish(timed.encode())
        self.published.duel(req.duel_id)

    def _dispatch(
        self,
        *,
        fresh: set[int] | frozenset[int] = frozenset(),
        again: bool = False,
        retry: bool = False,
    ) -> None:
        """Publish candidates of the open step: new assignments to workers with room, the
        ``fresh`` ones unassigned while no worker is known, and with ``again`` every pending
        candidate that is out to a live worker or was evaluated by one (its cached result is
        re-published, nothing is evaluated twice) or, with no worker known, unassigned. Only
        with ``retry`` (the failure policy's retry of a duel) are candidates whose episode
        failed assigned again, and candidates evaluated by a worker now gone sent to a live
        one (the oracle lacks their result: evaluating again is the only way to get it).
        Candidates of workers gone silent are taken back first."""
        if not self.driver.step_open:
            return
        now = self._now()
        for gone in self.pool.expire(now):
            self.warn(
                "worker_lost",
                f"worker {gone.worker} went silent with candidate {gone.candidate_id}; "
                "handing it to another worker",
            )
        pending = self.driver.pending_candidates()
        ids = [c.candidate_id for c in pending]
        new = {a.candidate_id for a in self.pool.assign(ids, now, retry=retry)}
        live = self.pool.live(now)
        self.counters["assigned"] = self.pool.assigned
        self.counters["reassigned"] = self.pool.reassigned
        self.counters["workers"] = len(live)
        for cand in pending:
            cid = cand.candidate_id
            worker = self.pool.worker_for(cid)
            if cid in new:
                self._publish_candidate(cand, worker)
            elif not live:
                if again or cid in fresh:
                    self._publish_candidate(cand, "")
            elif again and worker in live:
                self._publish_candidate(cand, worker)
            elif retry and worker:  # evaluated by a worker now gone
                self._publish_candidate(cand, live[0])

    def _publish_candidate(self, cand: CandidateMsg, worker: str) -> None:
        self._pub_candidate.publish(cand.assigned_to(worker).encode())
        self.published.candidate(cand.candidate_id)

    def _publish_pending(self, retry: bool = False) -> None:
        self._dispatch(again=True, retry=retry)
        for req in self.driver.pending_requests():
            self._publish_request(req)
        self._last_publish = self._now()

    def _publish_incumbent(self) -> None:
        inc = self.driver.incumbent()
        if inc is not None:
            self._pub_incumbent.publish(inc.encode())

    # ------------------------------------------------------------------ pool
    def _on_status(self, msg: object) -> None:
        status = Status.decode(msg)
        if isinstance(status, DecodeError):
            self.drop_decode(status)
            return
        worker = worker_of(status)
        if worker is None or status.run_id != self.config.run_id:
            return
        serving = status.state in SERVING_STATES
        if self.pool.heard(worker, serving, self._now()) and serving and self._started:
            self._dispatch()  # a new worker: give it work

    def _on_result(self, msg: object) -> None:
        result = EpisodeResult.decode(msg, expected_run_id=self.config.run_id)
        if isinstance(result, DecodeError):
            self.drop_decode(result)
            return
        ok = result.status is EpisodeStatus.OK
        self.pool.result(result.candidate_id, ok)
        if ok and result.candidate_id < self.driver.session.spent_ids[0]:
            self._evaluated.add(result.candidate_id)  # bounded: the run's own candidates
        if self._started and not self.finished:
            self._dispatch()  # the worker is free: its next candidate
            self._maybe_speculate()

    # ------------------------------------------------------------------ outcomes
    def _on_outcome(self, msg: object) -> None:
        decoded = DuelOutcome.decode(msg, expected_run_id=self.config.run_id)
        if isinstance(decoded, DecodeError):
            reason = decoded.reason.value
            self.drop(reason, str(decoded))
            return
        if self.finished or not self._started:
            detail = f"duel {decoded.duel_id} arrived while {self.state}"
            if decoded.kind is OutcomeKind.RETRACTED:
                self._refuse_retraction(decoded.duel_id, f"the run is {self.state}")
                return
            self.drop(Reason.NOT_RUNNING.value, detail)
            return
        arrived = self._now()
        verdict = self.driver.offer(decoded)
        if verdict.reason is Reason.FAILED:
            self.counters["failed_duels"] += 1
            self._failure(decoded.duel_id, verdict.detail)
            return
        if verdict.reason is Reason.DUPLICATE:
            self.counters["outcomes_duplicate"] += 1
            return
        if verdict.reason is Reason.RETRACTED:
            self._retracted(decoded.duel_id)
            return
        if verdict.reason is Reason.RETRACTION_REFUSED:
            self._refuse_retraction(decoded.duel_id, verdict.detail)
            return
        if not verdict.accepted:
            self.drop(verdict.reason.value, verdict.detail)
            return
        self.counters["duels_done"] = self.driver.n_duels
        self.counters["speculated"] = self.driver.speculated
        every = self.settings["progress_every"]
        if every and self.driver.n_duels % every == 0:
            self.get_logger().info(
                f"{self.driver.n_duels} duels, {self.driver.session.evaluations}/"
                f"{self.driver.session.budget} evaluations"
            )
        self._last_publish = self._now()  # progress: no re-publish right away
        self._deadline = self._last_publish + self.settings["duel_timeout_s"]
        if not self.driver.step_open:
            self._answered_at = arrived
            self._publish_incumbent()
            if self.driver.done:
                self._finish()
            else:
                self._next_step()
        else:
            self._speculate_soon()  # the ask's last duel may be the only one left

    def _retracted(self, duel_id: int) -> None:
        """A person took back the answer to ``duel_id``: the duel is pending again (the same
        request and candidates go out again), the duels asked after it are withdrawn."""
        self.counters["retractions"] = self.driver.retracted
        self.counters["duels_done"] = self.driver.n_duels
        self.get_logger().info(
            f"answer to duel {duel_id} taken back; asking it again "
            f"({self.driver.n_duels} duels answered)"
        )
        self._publish_incumbent()
        self._publish_pending()
        self._deadline = self._now() + self.settings["duel_timeout_s"]
        self._speculate_soon()

    def _refuse_retraction(self, duel_id: int, reason: str) -> None:
        self.counters[Reason.RETRACTION_REFUSED.value] += 1
        self.warn(
            Reason.RETRACTION_REFUSED.value,
            f"retraction of the answer to duel {duel_id} refused: {reason}",
        )

    def _failure(self, duel_id: int, reason: str) -> None:
        policy = self.settings["failure_policy"]
        tries = self._attempts.get(duel_id, 0)
        if policy == "stop" or tries >= self.settings["max_retries"]:
            self._stop(
                f"duel {duel_id} failed ({reason}); failure_policy={policy}, retries used {tries}"
            )
            return
        self._attempts[duel_id] = tries + 1
        self.counters["retries"] += 1
        self.warn("duel_retry", f"duel {duel_id} failed ({reason}); retry {tries + 1}")
        self._publish_pending(retry=True)
        self._deadline = self._now() + self.settings["duel_timeout_s"]

    def _finish(self) -> None:
        self.driver.cancel_speculation()
        self.finished = True
        self.finished_at = self._now()
        self.cpu_seconds = time.process_time() - self._cpu0
        self.state = "done"
        self.publish_status(0, f"run complete: {self.driver.n_duels} duels")
        self.get_logger().info(self.summary().format())

    def summary(self) -> RunSummary:
        """What the run produced, as far as this node knows (no episode returns)."""
        inc = self.driver.incumbent()
        rec = self.driver.recommendation() if self.driver.n_duels else None
        return RunSummary(
            run_id=self.config.run_id,
            state=self.state,
            error=self.error,
            duels=self.driver.n_duels,
            resumed_duels=self.resumed_duels,
            evaluations=self.driver.session.evaluations,
            budget=self.driver.session.budget,
            incumbent_id=None if inc is None else inc.candidate_id,
            incumbent_theta=() if inc is None else inc.theta,
            recommended_id=None if rec is None else rec.candidate_id,
            recommended_theta=() if rec is None else rec.theta,
            run_seconds=max(self.finished_at - self.started_at, 0.0),
            run_cpu_seconds=self.cpu_seconds,
        )

    def _stop(self, reason: str) -> None:
        self.driver.cancel_speculation()
        self.finished = True
        self.finished_at = self._now()
        self.error = reason
        self.state = "failed"
        self.get_logger().error(reason)
        self.publish_status(2, reason)
        self.get_logger().info(self.summary().format())


def main(argv: list[str] | None = None) -> NoReturn:
    """``ros2 run localpbo_ros optimizer_node --ros-args -p key:=value ...``."""
    from localpbo_ros.entry import run_node

    run_node(OptimizerNode, argv, stop_when_finished=True)


if __name__ == "__main__":
    main()
