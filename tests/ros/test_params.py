"""Parameters: declared with descriptors and ranges; bad values refused naming the parameter."""

from __future__ import annotations

import pytest
from localpbo_ros.optimizer_node import PARAMS, OptimizerNode
from localpbo_ros.params import ParameterError
from localpbo_ros.params import ParameterReason as PR
from localpbo_ros.recorder_node import RecorderNode
from localpbo_ros.sim_node import SimNode

from .conftest import SMALL_TASK


@pytest.mark.parametrize(
    ("overrides", "name", "reason"),
    [
        ({"budget": -3}, "budget", PR.OUT_OF_RANGE),
        ({"budget": "ten"}, "budget", PR.WRONG_TYPE),
        ({"seed": -1}, "seed", PR.OUT_OF_RANGE),
        ({"noise_fraction": 11.0}, "noise_fraction", PR.OUT_OF_RANGE),
        ({"algorithm": "simplex"}, "algorithm", PR.NOT_A_CHOICE),
        ({"task": "cartpole"}, "task", PR.NOT_A_CHOICE),
        ({"algorithm_options": "{not json"}, "algorithm_options", PR.BAD_JSON),
        ({"algorithm_options": "[1, 2]"}, "algorithm_options", PR.BAD_JSON),
        ({"algorithm_options": '{"frobnicate": 1}'}, "algorithm_options", PR.INVALID),
        ({"failure_policy": "ignore"}, "failure_policy", PR.NOT_A_CHOICE),
        ({"run_id": "bad id!"}, "run_id", PR.INVALID),
        ({"duel_timeout_s": 0.0}, "duel_timeout_s", PR.OUT_OF_RANGE),
        ({"task_options": '{"episode_steps": 0}'}, "task_options", PR.INVALID),
    ],
)
def test_optimizer_refuses_bad_parameter(ros, overrides, name, reason) -> None:
    base = {"algorithm": "sobol", "task_options": '{"episode_steps": 50, "value_range": 50.0}'}
    with pytest.raises(ParameterError, match=f"'{name}'") as info:
        OptimizerNode(context=ros.ctx, overrides={**base, **overrides})
    assert info.value.name == name
    assert info.value.reason is reason, info.value


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
        if isinstance(p.default, int) and not isinstance(p.default, bool):
            assert desc.integer_range and desc.integer_range[0].from_value == p.int_range[0]
        if isinstance(p.default, float):
            assert desc.floating_point_range
    assert node.config.options["task"] == SMALL_TASK


def test_follower_and_recorder_params(ros, tmp_path) -> None:
    with pytest.raises(ParameterError, match="'max_pending'") as info:
        SimNode(context=ros.ctx, overrides={"max_pending": 0})
    assert info.value.reason is PR.OUT_OF_RANGE
    with pytest.raises(ParameterError, match="'path'"):
        RecorderNode(context=ros.ctx, overrides={"path": str(tmp_path / "no" / "x.mcap")})
