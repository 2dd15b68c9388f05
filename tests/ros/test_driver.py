"""Driver bookkeeping against the optimizer used directly (independent reference)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from localpbo_ros.driver import Driver, rebuild

from localpbo_core.optimizers import Outcome, make_optimizer
from localpbo_core.problems import make_problem
from localpbo_msgs_py import DuelOutcome, DuelRequest

from .configs import run_config
from .conftest import SMALL_TASK


def config(**kw):
    base = dict(
        run_id="t1", algorithm="sobol", task="swimmer", seed=5, budget=12, task_options=SMALL_TASK
    )
    base.update(kw)
    return run_config(**base)


def rule(theta_a, theta_b) -> bool:
    """Scripted judge: the larger first coordinate wins."""
    return theta_a[0] > theta_b[0]


def test_driver_matches_direct_optimizer_and_rebuild() -> None:
    cfg = config()
    problem = make_problem("swimmer", **SMALL_TASK)
    ref = make_optimizer("sobol", 16, seed=5, budget=12, initial_design=2)
    drv = Driver(cfg)
    outcomes = []
    while not drv.done:
        work = drv.ask()
        ask = ref.ask()
        assert [c.candidate_id for c in work.candidates] == [c.id for c in ask.candidates]
        for c, r in zip(work.candidates, ask.candidates, strict=True):
            assert c.theta == tuple(problem.to_native(r.theta))
        for req, duel in zip(work.requests, ask.duels, strict=True):
            a = ref.history.candidates[duel.first].theta
            b = ref.history.candidates[duel.second].theta
            winner = duel.first if rule(a, b) else duel.second
            out = DuelOutcome.decisive(req, winner)
            assert drv.offer(out).accepted
            outcomes.append(out)
            ref.tell([Outcome(winner, duel.second if winner == duel.first else duel.first)])
    assert ref.done
    again = rebuild(cfg, outcomes)
    assert again.driver.done and again.refused == 0
    assert [c.candidate_id for c in again.proposed] == list(range(12))
    inc = again.driver.incumbent()
    assert inc is not None and inc.candidate_id == ref.incumbent.id


def test_offer_refusals_leave_state_unchanged() -> None:
    drv = Driver(config())
    work = drv.ask()
    req = work.requests[0]
    before = drv.session.optimizer.history
    bad = [
        (
            DuelOutcome.decisive(
                DuelRequest("other", req.duel_id, req.first_id, req.second_id), req.first_id
            ),
            "wrong_run",
        ),
        (
            DuelOutcome.decisive(DuelRequest("t1", 7, req.first_id, req.second_id), req.first_id),
            "unknown_duel",
        ),
        (
            DuelOutcome.decisive(
                DuelRequest("t1", req.duel_id, req.second_id, req.first_id), req.first_id
            ),
            "mismatched_duel",
        ),
        (DuelOutcome.indifferent(req), "unsupported_kind"),
        (DuelOutcome.failed(req, "episode failed"), "failed"),
    ]
    for out, reason in bad:
        verdict = drv.offer(out)
        assert not verdict.accepted and verdict.reason.value == reason
        assert drv.session.optimizer.history == before and drv.step_open
    good = DuelOutcome.decisive(req, req.first_id)
    assert drv.offer(good).accepted
    history = drv.session.optimizer.history
    assert drv.offer(good).reason.value == "duplicate"
    assert drv.offer(DuelOutcome.decisive(req, req.second_id)).reason.value == "repeated"
    assert drv.session.optimizer.history == history


@pytest.mark.parametrize(
    ("kw", "field"),
    [
        ({"algorithm": "nope"}, "algorithm"),
        ({"task": "nope"}, "problem"),
        ({"budget": 1}, "budget"),
        ({"noise_fraction": -1.0}, "noise_fraction"),
        ({"failure_policy": "ignore"}, "failure_policy"),
        ({"task_options": {"episode_steps": 50}}, "noise_fraction"),
    ],
)
def test_make_run_config_names_bad_setting(kw, field) -> None:
    with pytest.raises(ValueError, match=field):
        config(**kw)


def test_task_box_is_native_units() -> None:
    cfg = config()
    problem = make_problem("swimmer", **SMALL_TASK)
    assert cfg.lower == tuple(problem.to_native(np.zeros(16)))
    assert cfg.upper == tuple(problem.to_native(np.ones(16)))


def test_run_config_records_the_noise_scale_and_old_configs_keep_theirs() -> None:
    import dataclasses

    from localpbo_ros.driver import make_run_config, settings_of
    from localpbo_sims import MAX_MIN_VALUE_RANGES, VALUE_RANGES

    from localpbo_core.session import build_problem
    from localpbo_core.settings import RunSettings

    config = make_run_config("vr", RunSettings(algorithm="sobol", problem="hopper", budget=4))
    assert config.options["task"] == {"value_range": VALUE_RANGES["hopper"]}
    assert build_problem(settings_of(config)).value_range == VALUE_RANGES["hopper"]
    # a config recorded before the task recorded it: the max - min scale of that time
    old = dataclasses.replace(config, options={**config.options, "task": {}})
    assert settings_of(old).problem_options == {"value_range": MAX_MIN_VALUE_RANGES["hopper"]}
    # a resumed old run records the scale explicitly: still the same run, another scale is not
    from localpbo_ros.bagtools import same_run_config

    explicit = dataclasses.replace(
        config, options={**config.options, "task": {"value_range": MAX_MIN_VALUE_RANGES["hopper"]}}
    )
    assert same_run_config(old, explicit) and same_run_config(explicit, old)
    assert not same_run_config(old, config)
    # ... but only for the calibrated definition; others had (and have) no default scale
    steps = dataclasses.replace(config, options={**config.options, "task": {"episode_steps": 9}})
    assert settings_of(steps).problem_options == {"episode_steps": 9}
    # an explicit scale is kept either way; synthetic problems record nothing
    given = make_run_config(
        "vr",
        RunSettings(
            algorithm="sobol", problem="hopper", budget=4, problem_options={"value_range": 5.0}
        ),
    )
    assert given.options["task"] == {"value_range": 5.0}
    assert settings_of(given).problem_options == {"value_range": 5.0}
    synthetic = make_run_config("vr", RunSettings(algorithm="sobol", problem="hartmann6"))
    assert synthetic.options["task"] == {}
    assert settings_of(synthetic).problem_options == {}


def _retraction_run(bag: Path | None = None) -> tuple[Driver, list[DuelOutcome], dict[str, int]]:
    """A Hartmann run whose person takes back two answers (the second after re-answering the
    first differently), with one refused retraction; written to ``bag`` as a node would."""
    from localpbo_ros.driver import make_run_config

    from localpbo_core.settings import RunSettings
    from localpbo_msgs_py import EpisodeResult
    from localpbo_msgs_py.bag import BagWriter
    from localpbo_msgs_py.topics import (
        ALL_TOPICS,
        CANDIDATE,
        DUEL_OUTCOME,
        DUEL_REQUEST,
        EPISODE_RESULT,
        RUN_CONFIG,
    )

    settings = RunSettings(
        algorithm="turpbo", problem="hartmann6", seed=3, budget=12, tie_threshold=0.5
    )
    cfg = make_run_config("undo", settings, person=True)
    drv = Driver(cfg)
    problem = make_problem("hartmann6")
    writer = BagWriter(bag) if bag is not None else None
    if writer is not None:
        writer.add_suite_topics(ALL_TOPICS)
        writer.write(RUN_CONFIG.name, cfg.encode())
    outcomes: list[DuelOutcome] = []
    values: dict[int, float] = {}
    counts = {"retracted": 0, "refused": 0}

    def publish(work) -> None:  # type: ignore[no-untyped-def]
        for c in work.candidates:
            values[c.candidate_id] = float(problem.evaluate_native(np.asarray(c.theta), 0))
            if writer is not None:
                writer.write(CANDIDATE.name, c.encode())
                res = EpisodeResult.ok(cfg.run_id, c.candidate_id, values[c.candidate_id])
                writer.write(EPISODE_RESULT.name, res.encode())
        if writer is not None:
            for r in work.requests:
                writer.write(DUEL_REQUEST.name, r.encode())

    def send(out: DuelOutcome) -> None:
        outcomes.append(out)
        if writer is not None:
            writer.write(DUEL_OUTCOME.name, out.encode())
        verdict = drv.offer(out)
        if out.kind.value == "retracted":
            key = "retracted" if verdict.reason.value == "retracted" else "refused"
            counts[key] += 1
            if key == "retracted":  # the node publishes the duel again
                publish(type(work)((), drv.pending_requests()))
            return
        assert verdict.accepted, verdict
        if not drv.step_open and not drv.done:
            publish(drv.ask())

    work = drv.ask()
    publish(work)
    n = 0
    while not drv.done:
        (req,) = drv.pending_requests()
        best = req.first_id if values[req.first_id] > values[req.second_id] else req.second_id
        worst = req.second_id if best == req.first_id else req.first_id
        if n == 6:  # a slip of the finger, taken back at once
            send(DuelOutcome.decisive(req, worst))
            send(DuelOutcome.retracted(req))
        if n == 8:  # answered, next one answered too, both taken back, latest first
            send(DuelOutcome.decisive(req, worst))
            (nxt,) = drv.pending_requests()
            send(DuelOutcome.indifferent(nxt))
            send(DuelOutcome.retracted(req))  # not the latest: refused
            send(DuelOutcome.retracted(nxt))
            send(DuelOutcome.retracted(req))
        send(DuelOutcome.decisive(req, best))
        n += 1
    if writer is not None:
        writer.close()
    return drv, outcomes, counts


def test_retractions_rebuild_the_same_run_and_spend_no_id_twice() -> None:
    drv, outcomes, counts = _retraction_run()
    assert counts == {"retracted": 3, "refused": 1} and drv.retracted == 3
    again = rebuild(drv.config, outcomes)
    assert again.driver.done and again.retracted == 3 and again.refused == 1
    ids = [c.candidate_id for c in again.proposed]
    assert len(ids) == len(set(ids)) == 12 + 3  # three discarded candidates keep their ids
    assert [c.theta.tobytes() for c in again.driver.session.optimizer.history.candidates] == [
        c.theta.tobytes() for c in drv.session.optimizer.history.candidates
    ]
    duel_ids = [r.duel_id for r in again.requests]
    assert len(duel_ids) == len(set(duel_ids))
    # the retracted run is the run that only got the kept answers
    kept = [o for o in drv.accepted]
    plain = Driver(drv.config)
    plain.ask()
    for out in kept:
        (req,) = plain.pending_requests()
        if out.winner_id is None:
            answer = DuelOutcome.indifferent(req)
        else:
            # ids differ after a retraction: map the winner by its side of the duel
            answer = DuelOutcome.decisive(
                req, req.first_id if out.winner_id == out.first_id else req.second_id
            )
        assert plain.offer(answer).accepted
        if not plain.step_open and not plain.done:
            plain.ask()
    assert plain.done
    assert [c.theta.tobytes() for c in plain.session.optimizer.history.candidates] == [
        c.theta.tobytes() for c in drv.session.optimizer.history.candidates
    ]


def test_only_a_run_a_person_judges_takes_answers_back() -> None:
    from localpbo_ros.driver import make_run_config

    from localpbo_core.session import Reason
    from localpbo_core.settings import RunSettings

    settings = RunSettings(algorithm="sobol", problem="hartmann6", seed=1, budget=6)
    for person, expected in ((False, Reason.RETRACTION_REFUSED), (True, Reason.RETRACTED)):
        drv = Driver(make_run_config("p", settings, person=person))
        drv.ask()
        req = drv.pending_requests()[0]
        assert drv.offer(DuelOutcome.decisive(req, req.first_id)).accepted
        verdict = drv.offer(DuelOutcome.retracted(req))
        assert verdict.reason is expected, verdict
        if not person:
            assert "person" in verdict.detail and drv.n_duels == 1


def test_a_bag_with_retractions_verifies_and_resumes(tmp_path: Path) -> None:
    from localpbo_ros.bagtools import load_run
    from localpbo_ros.commands import main as cli_main
    from localpbo_ros.replay import verify

    bag = tmp_path / "undo.mcap"
    _, outcomes, _ = _retraction_run(bag)
    report = verify(bag)
    assert report.ok, report.format()
    assert report.candidates_checked == 15 and report.outcomes_used == 11
    assert cli_main(["replay", "--verify", str(bag)]) == 0
    # a bag whose recorded retraction is dropped no longer verifies: the check can fail
    cut = tmp_path / "tampered.mcap"
    _copy(bag, cut, skip=lambda out: out.kind.value == "retracted")
    assert not verify(cut).ok
    # stopped just after the last retraction: the resumed run continues from the same state
    last = max(i for i, o in enumerate(outcomes) if o.kind.value == "retracted")
    stop = tmp_path / "stopped.mcap"
    _copy(bag, stop, keep=last + 1)
    resumed = tmp_path / "resumed.mcap"
    _resume_with_a_person(stop, resumed, tmp_path / "judge")
    run = load_run(resumed)
    assert [o.kind.value for o in run.outcomes[: last + 1]] == [
        o.kind.value for o in outcomes[: last + 1]
    ]
    report = verify(resumed)
    assert report.ok and report.candidates_checked == 15, report.format()
    prefix = {c.candidate_id: c.theta for c in load_run(stop).candidates.values()}
    assert {k: run.candidates[k].theta for k in prefix} == prefix


def _resume_with_a_person(bag: Path, out: Path, state_dir: Path) -> None:
    """``run --resume`` of a person's run, the person scripted over the judge's HTTP API
    (answers ``a`` to every duel)."""
    import threading

    from localpbo_ros.suite import run_suite

    from . import person

    urls: list[str] = []
    result: dict[str, object] = {}

    def run() -> None:
        result["summary"] = run_suite(
            {},
            out,
            resume=bag,
            judge={"state_dir": str(state_dir)},
            on_url=urls.append,
            timeout_s=300,
        )

    thread = threading.Thread(target=run, daemon=True)
    thread.start()
    while not urls and thread.is_alive():
        thread.join(0.05)
    duel = person.next_ready(urls[0])
    while duel is not None:
        assert person.answer(urls[0], duel, "a")[0] == 200
        duel = person.next_ready(urls[0], after=duel["duel_id"])
    thread.join(120)
    summary = result["summary"]
    assert getattr(summary, "state", None) == "done", summary


def _copy(src: Path, dst: Path, *, keep: int | None = None, skip=None) -> None:  # type: ignore[no-untyped-def]
    """``src`` up to its ``keep``-th outcome (all by default), without outcomes ``skip``s."""
    from localpbo_msgs_py.bag import BagWriter, read_messages
    from localpbo_msgs_py.topics import ALL_TOPICS, DUEL_OUTCOME

    seen = 0
    with BagWriter(dst) as writer:
        writer.add_suite_topics(ALL_TOPICS)
        for rec in read_messages(src):
            if rec.topic == DUEL_OUTCOME.name:
                if keep is not None and seen >= keep:
                    break
                seen += 1
                out = DuelOutcome.decode(rec.message)
                if skip is not None and isinstance(out, DuelOutcome) and skip(out):
                    continue
            writer.write(rec.topic, rec.message, log_time_ns=rec.log_time_ns)
