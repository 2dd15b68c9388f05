"""A controller written the way a user writes one, knowing nothing of localpbo.

A PID loop holds a heated block at a set point (first-order thermal plant, explicit Euler).
Gains ``kp``, ``ki``, ``kd`` are plain double parameters read at every step. The loop never
stops: a timer steps the plant and publishes the step's cost on ``/thermal/cost``
(``std_msgs/Float64``) at ``rate_hz``, also between trials and after an episode is done, as a
free-running controller does. ``/thermal/reset`` (``std_srvs/Trigger``) puts the block back at
ambient temperature and restarts the step count; after ``episode_steps`` steps it publishes
``/thermal/done`` (``std_msgs/Empty``) and keeps running.

:func:`trial_costs` computes the costs of the first ``n`` steps after a reset offline, from the
same code, so a test can check each recorded score against the trial's own cost.
"""

from __future__ import annotations

import sys

import rclpy
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from std_msgs.msg import Empty, Float64
from std_srvs.srv import Trigger

AMBIENT = 20.0
SET_POINT = 60.0
DT = 0.05
HEAT_LOSS = 0.4
CAPACITY = 2.0
U_MAX = 100.0


class Plant:
    """A heated block under PID control; ``step`` returns that step's cost."""

    def __init__(self) -> None:
        self.temp = AMBIENT
        self.integral = 0.0
        self.prev_error = SET_POINT - AMBIENT

    def step(self, kp: float, ki: float, kd: float) -> float:
        error = SET_POINT - self.temp
        self.integral += error * DT
        derivative = (error - self.prev_error) / DT
        self.prev_error = error
        u = min(max(kp * error + ki * self.integral + kd * derivative, 0.0), U_MAX)
        self.temp += DT * (u - HEAT_LOSS * (self.temp - AMBIENT)) / CAPACITY
        return (SET_POINT - self.temp) ** 2 / 100.0 + 1e-4 * u * u


def trial_costs(kp: float, ki: float, kd: float, n: int) -> list[float]:
    """The costs of the first ``n`` steps after a reset with these gains."""
    plant = Plant()
    return [plant.step(kp, ki, kd) for _ in range(n)]


class ThermalController(Node):
    def __init__(self) -> None:
        super().__init__("thermal")
        self.declare_parameter("kp", 1.0)
        self.declare_parameter("ki", 0.1)
        self.declare_parameter("kd", 0.1)
        self.declare_parameter("rate_hz", 200.0)
        self.declare_parameter("episode_steps", 100)
        self.plant = Plant()
        self.steps = 0
        self.cost_pub = self.create_publisher(Float64, "/thermal/cost", 1000)
        self.done_pub = self.create_publisher(Empty, "/thermal/done", 10)
        self.create_service(Trigger, "/thermal/reset", self.on_reset)
        rate = self.get_parameter("rate_hz").value
        self.create_timer(1.0 / rate, self.on_tick)

    def on_reset(self, request: Trigger.Request, response: Trigger.Response) -> Trigger.Response:
        self.plant = Plant()
        self.steps = 0
        response.success = True
        return response

    def on_tick(self) -> None:
        kp, ki, kd = (self.get_parameter(g).value for g in ("kp", "ki", "kd"))
        self.cost_pub.publish(Float64(data=self.plant.step(kp, ki, kd)))
        self.steps += 1
        if self.steps == self.get_parameter("episode_steps").value:
            self.done_pub.publish(Empty())


def main() -> None:
    if {"-h", "--help"} & set(sys.argv[1:]):
        print(
            "usage: python -m localpbo_ros.benchmarks.thermal_controller "
            "[--ros-args -p rate_hz:=400.0 ...]"
        )
        return
    rclpy.init(args=sys.argv)
    node = ThermalController()
    print("thermal controller up", flush=True)
    try:
        rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass


if __name__ == "__main__":
    main()
