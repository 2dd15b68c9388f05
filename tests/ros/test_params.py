"""Parameters: declared with descriptors and ranges; bad values refused naming the parameter."""

from __future__ import annotations

import pytest
from localpbo_ros.optimizer_node import PARAMS, OptimizerNode
from localpbo_ros.params import ParameterError
from localpbo_ros.recorder import RecorderNode
from localpbo_ros.sim_node import SimNode

from .conftest import SMALL_TASK


@pytest.mark.parametrize(
    ("overrides", "name"),
    [
        ({"budget": -3}, "budget"),
        ({"budget": "ten"}, "budget"),
        ({"seed": -1}, "seed"),
        ({"noise_fraction": 11.0}, "noise_fraction"),
        ({"algorithm": "simplex"}, "algorithm"),
        ({"task": "cartpole"}, "task"),
        ({"algorithm_options": "{not json"}, "algorithm_options"),
        ({"algorithm_options": "[1, 2]"}, "algorithm_options"),
        ({"algorithm_options": '{"frobnicate": 1}'}, "algorithm_options"),
        ({"failure_policy": "ignore"}, "failure_policy"),
        ({"run_id": "bad id!"}, "run_id"),
        ({"duel_timeout_s": 0.0}, "duel_timeout_s"),
        ({"task_options": '{"episode_steps": 0}'}, "task_options"),
    ],
)
def test_optimizer_refuses_bad_parameter(ros, overrides, name) -> None:
    base = {"algorithm": "sobol", "task_options": '{"episode_steps": 50, "value_range": 50.0}'}
    with pytest.raises(ParameterError, match=f"'{name}'"):
        OptimizerNode(context=ros.ctx, overrides={**base, **overrides})


def test_descriptors_have_ranges(ros) -> None:
    node = ros.add(
        OptimizerNode(
            context=ros.ctx,
            overrides={
                "algorithm": "sobol",
                "task_options": '{"episode_steps": 50, "value_range": 50.0}',
            },
        )
    )
    for p in PARAMS:
        desc = node.describe_parameter(p.name)
        assert desc.read_only and desc.description
        if isinstance(p.default, int):
            assert desc.integer_range and desc.integer_range[0].from_value == p.int_range[0]
        if isinstance(p.default, float):
            assert desc.floating_point_range
    assert node.config.options["task"] == SMALL_TASK


def test_follower_and_recorder_params(ros, tmp_path) -> None:
    with pytest.raises(ParameterError, match="'max_pending'"):
        SimNode(context=ros.ctx, overrides={"max_pending": 0})
    with pytest.raises(ParameterError, match="'path'"):
        RecorderNode(context=ros.ctx, overrides={"path": str(tmp_path / "no" / "x.mcap")})
