"""param_bridge_node: target checks, trials, failures, restoring the target, hostile input."""

from __future__ import annotations

import json
import math
import time
from pathlib import Path
from typing import Any

import pytest
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from localpbo_examples.pid_controller_node import BRIDGE_SETTINGS, PidControllerNode
from localpbo_examples.plant import PlantConfig, episode_cost
from localpbo_ros.bridge import (
    Sample,
    ScoreWindow,
    TargetParameter,
    TrialWindow,
    check_listed,
    check_target,
    target_names,
)
from localpbo_ros.driver import make_run_config
from localpbo_ros.param_bridge_node import ParamBridgeNode
from localpbo_ros.replay import verify
from localpbo_ros.suite import run_suite
from rcl_interfaces.msg import FloatingPointRange, ParameterDescriptor
from rclpy.context import Context
from rclpy.node import Node
from std_msgs.msg import Empty, Float64
from std_srvs.srv import Trigger

from localpbo_core.settings import RunSettings
from localpbo_core.space import load_space, parse_space
from localpbo_core.validation import SettingError
from localpbo_msgs_py import CandidateMsg, EpisodeResult, Status
from localpbo_msgs_py.topics import CANDIDATE, EPISODE_RESULT, RUN_CONFIG, STATUS

REPO = Path(__file__).resolve().parents[2]
PID_SPACE = REPO / "ros_ws/src/localpbo_examples/config/pid_space.yaml"
ORIGINAL = (1.0, 0.1, 0.1)


# ---------------------------------------------------------------------- plain-Python parts
@pytest.mark.parametrize(
    ("kind", "reduce", "expected"),
    [
        ("reward", "mean", 2.0),
        ("reward", "sum", 6.0),
        ("reward", "last", 3.0),
        ("reward", "min", 1.0),
        ("reward", "max", 3.0),
        ("cost", "sum", -6.0),
        ("cost", "max", -3.0),
    ],
)
def test_score_window_reduces(kind: str, reduce: str, expected: float) -> None:
    window = ScoreWindow(kind, reduce)
    assert not window.add(5.0)  # closed: not taken
    window.start()
    for v in (1.0, 2.0, 3.0):
        assert window.add(v)
    assert not window.add(math.nan) and not window.add(math.inf)
    assert window.close() == expected
    window.start()
    assert window.close() is None  # no samples: no score


def test_score_window_refuses_unknown_kinds() -> None:
    with pytest.raises(SettingError) as err:
        ScoreWindow("utility", "mean")
    assert err.value.field == "score_kind"
    with pytest.raises(SettingError) as err:
        ScoreWindow("cost", "median")
    assert err.value.field == "score_reduce"


def test_mapping_names_the_targets() -> None:
    space = load_space(PID_SPACE)
    assert target_names(space, {}) == ("kp", "ki", "kd")
    assert target_names(space, {"kp": "pid.p"}) == ("pid.p", "ki", "kd")
    for mapping, field in (
        ({"kq": "x"}, "mapping.kq"),
        ({"kp": ""}, "mapping.kp"),
        ({"kp": "kd"}, "mapping"),
    ):
        with pytest.raises(SettingError) as err:
            target_names(space, mapping)
        assert err.value.field == field


def test_check_target_names_the_parameter() -> None:
    space = parse_space({"parameters": [{"name": "g", "lower": 0.5, "upper": 5.0}]})
    good = TargetParameter("g", True, True, False, ((0.0, 10.0),))
    check_target(space, ("g",), {"g": good})
    cases = {
        "has no parameter 'g'": TargetParameter("g", False),
        "not a double": TargetParameter("g", True, False),
        "read-only": TargetParameter("g", True, True, True),
        "accepts [0.0, 1.0]": TargetParameter("g", True, True, False, ((0.0, 1.0),)),
    }
    for text, info in cases.items():
        with pytest.raises(SettingError) as err:
            check_target(space, ("g",), {"g": info})
        assert err.value.field == "target.g" and text in err.value.reason


def test_run_config_carries_the_space_and_rebuilds_from_it() -> None:
    from localpbo_ros.driver import Driver, problem_of
    from localpbo_ros.optimizer_node import PARAMS, config_from_settings, settings_from_config

    params = {p.name: p.default for p in PARAMS}
    params = {k: json.loads(v) if k.endswith("_options") else v for k, v in params.items()}
    config = config_from_settings({**params, "space": str(PID_SPACE), "budget": 12})
    assert config.task == "space:pid" and config.lower == (0.1, 0.01, 0.01)
    recorded = config.options["space"]["parameters"][0]
    assert recorded["unit"] == "N/m" and recorded["log"] is True
    assert problem_of(config) == load_space(PID_SPACE)
    first = Driver(config).ask().candidates[0]  # the warm start: today's gains
    assert first.theta == pytest.approx(ORIGINAL, rel=1e-12)
    again = settings_from_config(config)  # what run --resume feeds the node
    again = {k: json.loads(v) if k.endswith("_options") else v for k, v in again.items()}
    assert config_from_settings({**params, **again}).to_json() == config.to_json()


def test_a_bad_space_parameter_is_refused_by_name(tmp_path: Path) -> None:
    from localpbo_ros.optimizer_node import PARAMS, config_from_settings
    from localpbo_ros.params import ParameterError

    bad = tmp_path / "bad.yaml"
    bad.write_text("parameters:\n  - {name: kp, lower: 0, upper: 1, log: true}\n")
    params = {p.name: p.default for p in PARAMS}
    params = {k: json.loads(v) if k.endswith("_options") else v for k, v in params.items()}
    with pytest.raises(ParameterError) as err:
        config_from_settings({**params, "space": str(bad)})
    assert err.value.name == "space" and "space.kp.lower" in err.value.problem


# ---------------------------------------------------------------------- in-process nodes
class Target(Node):
    """A controller stand-in: parameters of every kind the bridge must refuse or accept."""

    def __init__(self, ctx: Context) -> None:
        super().__init__("target", context=ctx)
        self.sets: list[dict[str, Any]] = []

        def ranged(lo: float, hi: float, read_only: bool = False) -> ParameterDescriptor:
            desc = ParameterDescriptor(read_only=read_only)
            desc.floating_point_range = [FloatingPointRange(from_value=lo, to_value=hi)]
            return desc

        self.declare_parameter("gain", 1.0, ranged(0.0, 10.0))
        self.declare_parameter("locked", 1.0, ranged(0.0, 10.0, read_only=True))
        self.declare_parameter("count", 1)
        self.declare_parameter("narrow", 0.5, ranged(0.0, 1.0))
        self.add_post_set_parameters_callback(
            lambda ps: self.sets.append({p.name: p.value for p in ps})
        )


def bridge_config(run_id: str = "br") -> Any:
    space = parse_space({"parameters": [{"name": "g", "lower": 0.5, "upper": 5.0}]})
    settings = RunSettings(algorithm="sobol", problem=space.name, budget=4, noise_fraction=0.0)
    return make_run_config(run_id, settings, space=space)


def start_bridge(ros: Any, target_param: str, **overrides: Any) -> ParamBridgeNode:
    ros.add(Target(ros.ctx))
    settings = {
        "target_node": "/target",
        "mapping": json.dumps({"g": target_param}),
        "score_topic": "/score",
        "done_topic": "/done",
        "done_service": "/bridge_done",
        "trial_duration_s": 0.2,
        "target_wait_s": 10.0,
        **overrides,
    }
    bridge = ros.add(ParamBridgeNode(context=ros.ctx, overrides=settings))
    ros.publish(RUN_CONFIG, bridge_config().encode())
    assert ros.spin_until(lambda: bridge.phase in ("ready", "refused"), 20)
    return bridge


@pytest.mark.parametrize(
    ("param", "text"),
    [
        ("missing", "has no parameter 'missing'"),
        ("locked", "is read-only"),
        ("count", "is not a double"),
        ("narrow", "accepts [0.0, 1.0]"),
    ],
)
def test_bridge_refuses_a_target_that_cannot_take_the_space(
    ros: Any, param: str, text: str
) -> None:
    results = ros.collect(EPISODE_RESULT)
    bridge = start_bridge(ros, param)
    assert bridge.phase == "refused" and bridge.finished and bridge.state == "failed"
    assert f"target.{param}" in bridge.error and text in bridge.error
    ros.publish(CANDIDATE, CandidateMsg("br", 0, (1.0,)).encode())
    assert ros.spin_until(lambda: len(results) == 1, 10)
    res = EpisodeResult.decode(results[0])
    assert isinstance(res, EpisodeResult) and res.status.value == "failed"
    assert text in res.error


def test_trial_scores_and_restores_on_close(ros: Any) -> None:
    results = ros.collect(EPISODE_RESULT)
    bridge = start_bridge(ros, "gain", score_kind="reward", score_reduce="sum")
    target = ros.nodes[1]
    assert bridge.phase == "ready"
    ros.publish(CANDIDATE, CandidateMsg("br", 0, (2.5,)).encode())
    assert ros.spin_until(lambda: bridge.phase == "trial", 10)
    assert target.get_parameter("gain").value == 2.5
    for v in (1.0, 2.0):
        ros.publish_msg("/score", Float64(data=v))
    assert ros.spin_until(lambda: bridge.window.count == 2, 10)
    ros.publish_msg("/done", Empty())
    assert ros.spin_until(lambda: len(results) == 1, 10)
    res = EpisodeResult.decode(results[0])
    assert isinstance(res, EpisodeResult) and res.episode_return == 3.0
    # a repeated candidate gets the stored result, no second trial
    ros.publish(CANDIDATE, CandidateMsg("br", 0, (2.5,)).encode())
    assert ros.spin_until(lambda: len(results) == 2, 10)
    assert bridge.counters["episodes"] == 1 and bridge.counters["results_repeated"] == 1
    bridge.close()
    assert target.get_parameter("gain").value == 1.0
    assert target.sets == [{"gain": 2.5}, {"gain": 1.0}]


def test_a_service_that_does_not_answer_fails_the_episode(ros: Any) -> None:
    deaf = Node("deaf", context=ros.ctx)  # serves reset but is never spun
    deaf.create_service(Trigger, "/deaf/reset", lambda req, res: res)
    results = ros.collect(EPISODE_RESULT)
    bridge = start_bridge(ros, "gain", reset_service="/deaf/reset", service_timeout_s=0.3)
    target = ros.nodes[1]
    ros.publish(CANDIDATE, CandidateMsg("br", 0, (4.0,)).encode())
    assert ros.spin_until(lambda: len(results) == 1, 10)
    res = EpisodeResult.decode(results[0])
    assert isinstance(res, EpisodeResult) and res.status.value == "failed"
    assert "timeout" in res.error
    assert target.get_parameter("gain").value == 4.0
    bridge.close()
    assert target.get_parameter("gain").value == 1.0
    deaf.destroy_node()


def test_hostile_input_is_dropped_and_counted(ros: Any) -> None:
    bridge = start_bridge(ros, "gain")

    def dropped(reason: str) -> int:
        return bridge.counters[f"dropped_{reason}"]

    ros.publish_msg("/done", Empty())  # no trial runs
    assert ros.spin_until(lambda: dropped("outside_trial") == 1, 10)
    client = ros.probe.create_client(Trigger, "/bridge_done")
    assert ros.spin_until(client.service_is_ready, 10)
    future = client.call_async(Trigger.Request())
    assert ros.spin_until(future.done, 10)
    assert not future.result().success and dropped("outside_trial") == 2
    ros.publish_msg("/score", Float64(data=1.0))  # outside a trial: counted, not taken
    assert ros.spin_until(lambda: bridge.counters["scores_outside_trial"] == 1, 10)
    bridge.window.start(time.time_ns(), 10**10)  # as in a trial
    for bad in (math.nan, math.inf, -math.inf):
        ros.publish_msg("/score", Float64(data=bad))
    assert ros.spin_until(lambda: dropped("non_finite") == 3, 10)
    assert bridge.window.close() == (None, "3 non-finite score samples in the trial")
    ros.publish(CANDIDATE, CandidateMsg("br", 0, (50.0,)).encode())  # outside the box
    ros.publish(CANDIDATE, CandidateMsg("other", 1, (1.0,)).encode())
    assert ros.spin_until(lambda: dropped("out_of_bounds") + dropped("wrong_run") == 2, 10)
    ros.publish(STATUS, DiagnosticArray(status=[DiagnosticStatus(name="junk")]))
    assert ros.spin_until(lambda: dropped("malformed") + dropped("wrong_type") >= 1, 10)
    assert bridge.phase == "ready" and bridge.counters["episodes"] == 0
    assert ros.nodes[1].sets == []  # nothing reached the target


# ---------------------------------------------------------------------- whole runs
class Controller(PidControllerNode):
    """The worked example, remembering every gain change and its gains when destroyed."""

    def __init__(self, ctx: Context) -> None:
        super().__init__(context=ctx)
        self.changes: list[tuple[float, float, float]] = []
        self.final: tuple[float, float, float] | None = None
        self.add_post_set_parameters_callback(lambda ps: self.changes.append(self.gains()))

    def destroy_node(self) -> None:
        self.final = self.gains()
        super().destroy_node()


def run_example(tmp_path: Path, bridge: dict[str, Any], **settings: Any) -> Any:
    made: list[Controller] = []

    def factory(ctx: Context) -> Controller:
        made.append(Controller(ctx))
        return made[-1]

    summary = run_suite(
        {
            "run_id": "pid",
            "space": str(PID_SPACE),
            "algorithm": "turpbo",
            "budget": 12,
            "seed": 0,
            **settings,
        },
        tmp_path / "pid.mcap",
        bridge={**BRIDGE_SETTINGS, **bridge},
        controllers=[factory],
        timeout_s=240,
    )
    return summary, made[0]


def test_example_improves_and_target_is_restored(tmp_path: Path) -> None:
    summary, controller = run_example(tmp_path, {})
    assert summary.state == "done", summary.error
    assert len(controller.changes) >= 12  # every candidate was applied
    assert controller.final == ORIGINAL
    config = PlantConfig()
    initial = episode_cost(*ORIGINAL, config)
    recommended = episode_cost(*summary.recommended_theta, config)
    assert recommended < initial
    assert summary.first_candidate_return == pytest.approx(-initial, rel=1e-9)
    report = verify(tmp_path / "pid.mcap")
    assert report.ok and report.candidates_checked == 12, report.format()


def test_target_restored_after_a_failed_run(tmp_path: Path) -> None:
    summary, controller = run_example(
        tmp_path,
        {"score_topic": "/nobody/publishes/this", "done_topic": "", "trial_duration_s": 0.2},
        failure_policy="stop",
        budget=4,
    )
    assert summary.state == "failed" and "has no publisher" in summary.error
    assert controller.changes and controller.changes[0] != ORIGINAL
    assert controller.final == ORIGINAL
    assert controller.changes[-1] == ORIGINAL


def test_bridge_is_a_pool_worker(ros: Any) -> None:
    results = ros.collect(EPISODE_RESULT)
    statuses = ros.collect(STATUS)
    bridge = start_bridge(ros, "gain", score_kind="reward", score_reduce="sum")
    target = ros.nodes[1]
    bridge.publish_status()
    assert ros.spin_until(lambda: len(statuses) > 0, 10)
    mine = [Status.decode(m) for m in statuses]
    assert any(s.node == "param_bridge_node" and s.info["worker"] == bridge.worker_id for s in mine)
    # assigned to another worker: skipped, no trial
    ros.publish(CANDIDATE, CandidateMsg("br", 0, (2.5,), "sim_node.0000abcd").encode())
    assert ros.spin_until(lambda: bridge.counters["candidates_for_others"] == 1, 10)
    assert bridge.phase == "ready" and target.get_parameter("gain").value == 1.0
    # assigned to this bridge: a trial, reported busy while it runs
    ros.publish(CANDIDATE, CandidateMsg("br", 1, (2.5,), bridge.worker_id).encode())
    assert ros.spin_until(lambda: bridge.phase == "trial", 10)
    assert bridge.status_info()["busy"] == "1"
    ros.publish_msg("/score", Float64(data=2.0))
    assert ros.spin_until(lambda: bridge.window.count == 1, 10)
    ros.publish_msg("/done", Empty())
    assert ros.spin_until(lambda: len(results) == 1, 10)
    res = EpisodeResult.decode(results[0])
    assert isinstance(res, EpisodeResult) and res.candidate_id == 1 and res.episode_return == 2.0
    assert bridge.status_info()["busy"] == ""
    bridge.close()


# ---------------------------------------------------------------------- the trial window
MS = 1_000_000


def feed(window: TrialWindow, samples: list[tuple[int, int, float]]) -> list[Sample]:
    """Offer (stamp in ms, sequence number, value) samples in arrival order."""
    return [window.add(v, t * MS, seq) for t, seq, v in samples]


def test_window_takes_only_samples_published_after_its_opening_answer() -> None:
    w = TrialWindow("reward", "sum")
    w.arm()  # set sent: samples of both trials may arrive before the answer that opens
    got = feed(w, [(8, 1, 100.0), (9, 2, 100.0), (11, 3, 1.0), (12, 4, 2.0)])
    assert got == [Sample.PENDING] * 4
    w.start(10 * MS, 1000 * MS)  # the reset's answer was published at 10 ms
    assert feed(w, [(13, 5, 3.0)]) == [Sample.TAKEN]
    assert w.count == 3 and w.close() == (6.0, "")


def test_a_done_taken_after_later_samples_still_ends_the_window_at_its_stamp() -> None:
    w = TrialWindow("reward", "sum")
    w.start(0, 10_000 * MS)
    feed(w, [(1, 1, 1.0), (2, 2, 2.0), (4, 3, 50.0), (5, 4, 60.0)])  # 4 and 5 ms: after done
    assert not w.complete
    assert w.end_at(3 * MS)  # the done message, published at 3 ms, taken last
    assert w.complete and w.count == 2
    assert w.close() == (3.0, "")
    w.start(100 * MS, None)
    assert not w.end_at(99 * MS)  # a done of an earlier trial does not end this one


def test_count_mode_is_exact_and_short_counts_fail() -> None:
    w = TrialWindow("cost", "mean", samples=3)
    w.start(0, 10_000 * MS)
    got = feed(w, [(1, 1, 1.0), (2, 2, 2.0), (3, 3, 3.0), (4, 4, 99.0)])
    assert got[-1] is Sample.AFTER and w.complete
    assert w.close() == (-2.0, "")
    w.start(10 * MS, 5 * MS)
    feed(w, [(11, 5, 1.0), (12, 6, 1.0), (16, 7, 1.0)])  # the third is past the duration
    assert w.close() == (None, "only 2 of 3 score samples in the trial")


@pytest.mark.parametrize(
    ("samples", "reason"),
    [
        ([(1, 1, 1.0), (2, 3, 1.0)], "1 score samples lost (sequence 1 -> 3)"),
        ([(1, 7, 1.0), (2, 1, 1.0)], "another publisher (sequence 1 after 7)"),
        ([(1, 1, 1.0), (2, 2, math.nan)], "1 non-finite score samples"),
        ([(1, 1, 1.0), (900, 2, 1.0)], "no score sample for 0.899 s"),
        ([(600, 1, 1.0)], "no score sample for 0.600 s"),
    ],
)
def test_a_trial_with_a_hole_fails_naming_it(samples: list[Any], reason: str) -> None:
    w = TrialWindow("reward", "mean", max_gap_ns=500 * MS)
    w.start(0, 10_000 * MS)
    feed(w, samples)
    score, why = w.close()
    assert score is None and reason in why


def test_silence_before_the_first_sample_is_a_stall_later_silence_is_not() -> None:
    w = TrialWindow("reward", "mean", max_gap_ns=500 * MS)
    w.start(0, 10_000 * MS)
    assert not w.stalled(400 * MS) and w.stalled(600 * MS)
    w.start(1000 * MS, 10_000 * MS)
    feed(w, [(1001, 1, 1.0)])
    assert not w.stalled(5000 * MS)  # the target may stop at the end of its episode
    assert w.close() == (1.0, "")


def test_the_first_missing_parameter_is_named_from_the_listing() -> None:
    space = parse_space(
        {
            "name": "pid",
            "parameters": [
                {"name": "kp", "lower": 0.1, "upper": 1.0},
                {"name": "ki", "lower": 0.1, "upper": 1.0},
                {"name": "kf", "lower": 0.1, "upper": 1.0},
                {"name": "kz", "lower": 0.1, "upper": 1.0},
            ],
        }
    )
    names = target_names(space, {})
    check_listed(space, names, {"kp", "ki", "kf", "kz"})  # all there: no refusal
    with pytest.raises(SettingError) as err:
        check_listed(space, names, {"kp", "ki", "kd", "use_sim_time"})
    assert err.value.field == "target.kf"
    assert "no parameter 'kf'" in err.value.reason and "also missing: kz" in err.value.reason
