"""The box around the ARS policy (``around_ars``) and the tasks' goal lines."""

from __future__ import annotations

import numpy as np
import pytest
from localpbo_sims import load_ars_policy, make_task
from localpbo_sims.tasks import ARS_RADII, GOALS


def test_centre_is_the_ars_policy_and_corners_are_its_perturbations() -> None:
    task = make_task("hopper", around_ars=0.1)
    ars = load_ars_policy("hopper").weights.ravel()
    np.testing.assert_allclose(task.to_native(np.full(task.dim, 0.5)), ars, atol=1e-12)
    np.testing.assert_allclose(task.to_native(np.zeros(task.dim)), ars - 0.1, atol=1e-12)
    np.testing.assert_allclose(task.to_native(np.ones(task.dim)), ars + 0.1, atol=1e-12)
    theta = np.random.default_rng(3).random(task.dim)
    assert task.evaluate(theta, 5) == task.evaluate_native(task.to_native(theta), 5)
    assert not task.calibrated and np.isnan(task.value_range)
    with pytest.raises(ValueError, match="W_ars"):
        task.evaluate_native(ars + 0.2, 5)


def test_perturbations_of_ars_last_long_enough_to_watch() -> None:
    """The reason for the default radius: most episodes last >= 1 s (the default box's
    random points mostly fall within 0.15 s)."""
    rng = np.random.default_rng(0)
    task = make_task("hopper", around_ars=ARS_RADII["hopper"])
    centred = [task.rollout(rng.random(task.dim), i).steps * 0.008 for i in range(8)]
    plain = make_task("hopper")
    box = [plain.rollout(rng.random(plain.dim), i).steps * 0.008 for i in range(8)]
    assert np.median(centred) >= 1.0 > np.median(box)


@pytest.mark.parametrize(
    ("options", "match"),
    [
        ({"around_ars": 0.0}, "positive radius"),
        ({"around_ars": True}, "expected a number"),
        ({"around_ars": 0.1, "weight_low": -2.0}, "keep their defaults"),
    ],
)
def test_bad_around_ars_refused(options: dict, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        make_task("hopper", **options)


def test_swimmer_has_no_ars_policy_to_centre_on() -> None:
    with pytest.raises(ValueError, match="no ARS policy"):
        make_task("swimmer", around_ars=0.1)


def test_every_task_says_what_better_means() -> None:
    for name in ("hopper", "walker2d", "swimmer"):
        assert make_task(name).goal == GOALS[name] and GOALS[name].startswith("Better = ")
