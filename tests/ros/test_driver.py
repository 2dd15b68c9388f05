"""Driver bookkeeping against the optimizer used directly (independent reference)."""

from __future__ import annotations

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
