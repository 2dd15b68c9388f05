"""What ``ros2 param list/get/describe/set`` and ``--ros-args -r __node:=`` see, through the
standard rcl_interfaces services of a node in this process."""

from __future__ import annotations

from typing import Any

import pytest
from localpbo_ros.optimizer_node import PARAMS, OptimizerNode
from localpbo_ros.oracle_node import OracleNode
from localpbo_ros.recorder_node import RecorderNode
from localpbo_ros.sim_node import SimNode
from rcl_interfaces.msg import Parameter, ParameterType, ParameterValue
from rcl_interfaces.srv import (
    DescribeParameters,
    GetParameters,
    ListParameters,
    SetParameters,
)

from localpbo_msgs_py import Status
from localpbo_msgs_py.topics import STATUS

OPT = {"algorithm": "sobol", "task_options": '{"episode_steps": 50, "value_range": 50.0}'}


_SERVICES = {
    DescribeParameters: "describe_parameters",
    GetParameters: "get_parameters",
    ListParameters: "list_parameters",
    SetParameters: "set_parameters",
}


def call(ros: Any, node: str, srv_type: Any, **request: Any) -> Any:
    """Call ``node``'s parameter service of type ``srv_type`` with a request of these fields."""
    name = f"/{node}/{_SERVICES[srv_type]}"
    client = ros.probe.create_client(srv_type, name)
    assert ros.spin_until(client.service_is_ready, 10), f"no service {name}"
    future = client.call_async(srv_type.Request(**request))
    assert ros.spin_until(future.done, 10), f"no answer from {name}"
    ros.probe.destroy_client(client)
    return future.result()


def test_parameters_listed_read_and_described(ros: Any) -> None:
    ros.add(OptimizerNode(context=ros.ctx, overrides={**OPT, "budget": 12}))
    listed = call(ros, "optimizer_node", ListParameters)
    assert {p.name for p in PARAMS} <= set(listed.result.names)
    got = call(
        ros, "optimizer_node", GetParameters, names=["budget", "algorithm", "noise_fraction"]
    )
    budget, algorithm, noise = got.values
    assert budget.type == ParameterType.PARAMETER_INTEGER and budget.integer_value == 12
    assert algorithm.string_value == "sobol"
    assert noise.double_value == 0.1
    described = call(
        ros,
        "optimizer_node",
        DescribeParameters,
        names=["budget", "noise_fraction", "failure_policy"],
    )
    budget_d, noise_d, policy_d = described.descriptors
    assert all(d.read_only for d in described.descriptors)
    assert (budget_d.integer_range[0].from_value, budget_d.integer_range[0].to_value) == (
        0,
        100000,
    )
    assert noise_d.floating_point_range[0].to_value == 10.0
    assert "retry" in policy_d.description and "stop" in policy_d.description


def test_set_of_a_read_only_parameter_is_refused(ros: Any) -> None:
    node = ros.add(OptimizerNode(context=ros.ctx, overrides=OPT))
    budget = Parameter(
        name="budget", value=ParameterValue(type=ParameterType.PARAMETER_INTEGER, integer_value=5)
    )
    answer = call(ros, "optimizer_node", SetParameters, parameters=[budget])
    (result,) = answer.results
    assert not result.successful and "read-only" in result.reason
    assert node.get_parameter("budget").value == 0


@pytest.mark.parametrize(
    ("factory", "name", "overrides"),
    [
        (OptimizerNode, "optimizer_node", OPT),
        (SimNode, "sim_node", {}),
        (OracleNode, "oracle_node", {}),
        (RecorderNode, "recorder_node", None),
    ],
)
def test_node_names_match_the_executables_and_remap(
    ros: Any, tmp_path: Any, factory: Any, name: str, overrides: dict[str, Any] | None
) -> None:
    if overrides is None:
        overrides = {"path": str(tmp_path / "r.mcap")}
    plain = ros.add(factory(context=ros.ctx, overrides=overrides))
    assert plain.get_name() == name
    if hasattr(plain, "close"):
        plain.close()
    ros.remove(plain)
    if "path" in overrides:
        overrides = {"path": str(tmp_path / "r2.mcap")}
    renamed = ros.add(
        factory(
            context=ros.ctx, overrides=overrides, cli_args=["--ros-args", "-r", "__node:=other"]
        )
    )
    assert renamed.get_name() == "other"
    listed = call(ros, "other", ListParameters)
    assert listed.result.names
    statuses = ros.collect(STATUS)
    renamed.publish_status()
    assert ros.spin_until(lambda: bool(statuses), 5)
    status = Status.decode(statuses[-1])
    assert isinstance(status, Status) and status.node == "other"
    assert statuses[-1].status[0].name == "localpbo/other"
    if hasattr(renamed, "close"):
        renamed.close()
