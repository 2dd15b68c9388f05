"""Parameters: declared with descriptors and ranges; bad values and unknown names refused naming
the parameter; ``use_sim_time`` honoured without stopping the heartbeat."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest
from localpbo_ros.judge_node import JudgeNode
from localpbo_ros.optimizer_node import PARAMS, OptimizerNode
from localpbo_ros.oracle_node import OracleNode
from localpbo_ros.param_bridge_node import ParamBridgeNode
from localpbo_ros.params import ParameterError
from localpbo_ros.params import ParameterReason as PR
from localpbo_ros.recorder_node import RecorderNode
from localpbo_ros.sim_node import SimNode
from rcl_interfaces.msg import Parameter as RosParameter
from rcl_interfaces.msg import ParameterType, ParameterValue
from rcl_interfaces.srv import SetParameters

from localpbo_msgs_py import Status
from localpbo_msgs_py.topics import STATUS

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


NODES = {
    "optimizer_node": lambda ctx, o: OptimizerNode(context=ctx, overrides=o),
    "sim_node": lambda ctx, o: SimNode(context=ctx, overrides=o),
    "oracle_node": lambda ctx, o: OracleNode(context=ctx, overrides=o),
    "recorder_node": lambda ctx, o: RecorderNode(context=ctx, overrides=o),
    "param_bridge_node": lambda ctx, o: ParamBridgeNode(context=ctx, overrides=o),
    "judge_node": lambda ctx, o: JudgeNode(context=ctx, overrides=o),
}


@pytest.mark.parametrize("node", sorted(NODES))
def test_unknown_parameters_are_refused_with_the_nearest_names(ros, node) -> None:
    with pytest.raises(ParameterError) as info:
        NODES[node](ros.ctx, {"budgte": 30, "use_sim_time": True})
    assert info.value.name == "budgte" and info.value.reason is PR.UNKNOWN
    text = str(info.value)
    assert text.startswith("unknown parameter 'budgte' ("), text
    if node == "optimizer_node":
        assert text == "unknown parameter 'budgte' (did you mean 'budget'?)"
    else:  # nothing near: the names it takes, ROS's own included
        assert f"({node} takes: " in text and "use_sim_time" in text


def test_near_misses_of_other_parameters(ros) -> None:
    with pytest.raises(ParameterError, match=r"did you mean 'max_pending'\?"):
        SimNode(context=ros.ctx, overrides={"max_pendng": 3})
    with pytest.raises(ParameterError, match=r"did you mean 'use_sim_time'\?"):
        OracleNode(context=ros.ctx, overrides={"use_simtime": True})


def test_ros_own_parameters_pass(ros) -> None:
    node = ros.add(SimNode(context=ros.ctx, overrides={"use_sim_time": True}))
    assert node.get_parameter("use_sim_time").value is True


def test_unknown_ros_args_parameter_exits_2_naming_it() -> None:
    """What ``ros2 run localpbo_ros optimizer_node --ros-args -p budgte:=30`` prints."""
    env = {**os.environ, "ROS_AUTOMATIC_DISCOVERY_RANGE": "OFF"}
    cmd = [sys.executable, "-m", "localpbo_ros.optimizer_node", "--ros-args"]
    done = subprocess.run(
        [*cmd, "-p", "budgte:=30", "-p", "use_sim_time:=true"],
        env=env,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == 2, done.stderr[-2000:]
    assert "unknown parameter 'budgte' (did you mean 'budget'?)" in done.stderr
    assert "Traceback" not in done.stderr


def status_stamps(ros, name: str, seconds: float) -> list[int]:
    got = ros.collect(STATUS)
    ros.spin_for(seconds)
    mine = [Status.decode(m) for m in got]
    return [s.stamp_ns for s in mine if isinstance(s, Status) and s.node == name]


def test_use_sim_time_set_while_running_keeps_the_heartbeat(ros) -> None:
    """``ros2 param set /sim_node use_sim_time true`` with no /clock: status still every
    second (timers on the steady clock), and the stamps now follow the (absent) sim clock."""
    ros.add(SimNode(context=ros.ctx, overrides={"run_id": "simtime"}))
    before = status_stamps(ros, "sim_node", 2.5)
    assert len(before) >= 2 and all(s > 0 for s in before)
    client = ros.probe.create_client(SetParameters, "/sim_node/set_parameters")
    assert ros.spin_until(client.service_is_ready, 10)
    value = ParameterValue(type=ParameterType.PARAMETER_BOOL, bool_value=True)
    future = client.call_async(
        SetParameters.Request(parameters=[RosParameter(name="use_sim_time", value=value)])
    )
    assert ros.spin_until(future.done, 10)
    (result,) = future.result().results
    assert result.successful, result.reason
    after = status_stamps(ros, "sim_node", 3.5)
    assert len(after) >= 3, after  # the heartbeat goes on
    assert after[-1] == 0  # honoured: the ROS clock is sim time, and no /clock was published


def test_optimizer_refuses_a_hostile_space_file_naming_it(ros, tmp_path) -> None:
    """``optimizer_node -p space:=FILE``: the parameter, the file and the field."""
    binary = tmp_path / "gains.bin"
    binary.write_bytes(bytes(range(256)) * 8)
    big = tmp_path / "big.yaml"
    big.write_text("parameters: []\n" + "#" * (2 << 20))
    cases = {
        binary: f"invalid parameter 'space': space: file {binary}: is not a YAML mapping",
        big: f"invalid parameter 'space': space: file {big}: is {big.stat().st_size} bytes",
    }
    for path, says in cases.items():
        with pytest.raises(ParameterError) as info:
            OptimizerNode(context=ros.ctx, overrides={"algorithm": "sobol", "space": str(path)})
        assert info.value.name == "space" and str(info.value).startswith(says), info.value
