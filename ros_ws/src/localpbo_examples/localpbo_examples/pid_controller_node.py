"""``pid_controller_node``: a PID position loop on a simulated mass-spring-damper.

It knows nothing of localpbo: its gains ``kp``, ``ki``, ``kd`` are ordinary declared
parameters (with ranges) that take effect at the next control step, so ``ros2 param set`` or
``param_bridge_node`` can change them while it runs. A timer runs ``steps_per_tick`` control
steps every ``1/rate_hz`` seconds (the plant runs faster than real time when
``steps_per_tick × rate_hz × dt > 1``; the result does not depend on the rate).

Topics (private, under the node name, e.g. ``/pid_controller_node/cost``): publishes
``~/cost`` (``std_msgs/Float64``, the tracking cost of each control step) and
``~/trial_done`` (``std_msgs/Empty``, once an episode's ``episode_steps`` steps are done).
Service ``~/reset`` (``std_srvs/Trigger``): start a new episode (a step response from rest,
measurement noise re-seeded from ``seed``); before the first reset and between episodes the
loop waits (and publishes nothing), so every cost sample belongs to one episode. The plant and
controller are :mod:`localpbo_examples.plant`.
"""

from __future__ import annotations

from typing import Any, NoReturn, Unpack

from localpbo_ros.base import NodeOptions, node_arguments
from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import QoSProfile, ReliabilityPolicy
from std_msgs.msg import Empty, Float64
from std_srvs.srv import Trigger

from localpbo_examples.plant import PidLoop, PlantConfig

GAINS = {"kp": (1.0, 0.0, 200.0), "ki": (0.1, 0.0, 100.0), "kd": (0.1, 0.0, 50.0)}
"""Gain: (initial value, lower, upper) of its declared range."""

BRIDGE_SETTINGS = {
    "target_node": "/pid_controller_node",
    "reset_service": "/pid_controller_node/reset",
    "score_topic": "/pid_controller_node/cost",
    "score_kind": "cost",
    "score_reduce": "sum",
    "trial_samples": 300,
    "trial_duration_s": 30.0,
}
"""``param_bridge_node`` parameters that tune this node: one trial = one episode of the default
``episode_steps`` (300 cost samples, counted: exact even under load; ``~/trial_done`` could
overtake the last samples)."""

COST_QOS = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE)
"""Reliable, deep enough for a whole episode's costs in one burst."""


def _float(name: str, value: float, lo: float, hi: float, text: str, read_only: bool) -> Any:
    desc = ParameterDescriptor(name=name, description=text, read_only=read_only)
    desc.floating_point_range = [FloatingPointRange(from_value=lo, to_value=hi, step=0.0)]
    return value, desc


class PidControllerNode(Node):
    """The example controller (see module docstring)."""

    def __init__(self, **options: Unpack[NodeOptions]) -> None:
        super().__init__("pid_controller_node", **node_arguments(options))
        for gain, (value, lo, hi) in GAINS.items():
            self.declare_parameter(gain, *_float(gain, value, lo, hi, f"{gain} gain", False))
        rate = self.declare_parameter(
            "rate_hz", *_float("rate_hz", 100.0, 1.0, 10_000.0, "Timer rate (Hz).", True)
        ).value
        dt = self.declare_parameter(
            "dt", *_float("dt", 0.01, 1e-4, 1.0, "Simulated seconds per control step.", True)
        ).value
        per_tick = self._int("steps_per_tick", 10, 1, 10_000, "Control steps per timer tick.")
        steps = self._int("episode_steps", 300, 1, 10**7, "Control steps of one episode.")
        self.seed = self._int("seed", 0, 0, 2**31 - 1, "Seed of the measurement noise.")
        noise = self.declare_parameter(
            "noise_std", *_float("noise_std", 0.01, 0.0, 10.0, "Measurement noise std.", True)
        ).value
        self.loop = PidLoop(
            PlantConfig(dt=dt, noise_std=noise, episode_steps=steps), seed=self.seed
        )
        self.loop.stop()  # the first episode starts with the first reset
        self.steps_per_tick = per_tick
        self.episodes = 0
        self._cost = self.create_publisher(Float64, "~/cost", COST_QOS)
        self._done = self.create_publisher(Empty, "~/trial_done", 10)
        self.create_service(Trigger, "~/reset", self._on_reset)
        self.add_post_set_parameters_callback(self._on_set)
        self.create_timer(1.0 / rate, self._tick)

    def _int(self, name: str, value: int, lo: int, hi: int, text: str) -> int:
        desc = ParameterDescriptor(name=name, description=text, read_only=True)
        desc.integer_range = [IntegerRange(from_value=lo, to_value=hi, step=1)]
        return int(self.declare_parameter(name, value, desc).value)

    def gains(self) -> tuple[float, float, float]:
        """The current (kp, ki, kd)."""
        kp, ki, kd = (self.get_parameter(g).value for g in GAINS)
        return float(kp), float(ki), float(kd)

    def _on_set(self, params: list[Parameter]) -> None:
        text = ", ".join(f"{p.name}={p.value!r}" for p in params)
        self.get_logger().info(f"gains set: {text}")

    def _on_reset(self, request: Trigger.Request, response: Trigger.Response) -> Any:
        self.loop.reset(self.seed)
        response.success = True
        response.message = f"episode {self.episodes + 1} started"
        return response

    def _tick(self) -> None:
        if self.loop.done:
            return
        kp, ki, kd = self.gains()
        for _ in range(self.steps_per_tick):
            self._cost.publish(Float64(data=self.loop.step(kp, ki, kd)))
            if self.loop.done:
                self.episodes += 1
                self._done.publish(Empty())
                return


def main(argv: list[str] | None = None) -> NoReturn:
    """``ros2 run localpbo_examples pid_controller_node [--ros-args -p kp:=2.0 ...]``."""
    from localpbo_ros.entry import run_node

    run_node(PidControllerNode, argv, stop_when_finished=False)


if __name__ == "__main__":
    main()
