"""``localpbo run``: the three nodes and the recorder in one process.

A private ``Context`` with ``ROS_AUTOMATIC_DISCOVERY_RANGE=OFF`` (nothing leaves the process)
and one ``SingleThreadedExecutor`` driven from this thread. The optimizer starts once the
recorder is matched with the simulator's and oracle's publishers and the simulator, oracle
and recorder subscribe to its topics, so the bag holds the whole exchange.

Space runs (``bridge=``): ``param_bridge_node`` replaces the simulator and evaluates the
candidates on a controller node, either started in this process (``controllers=``, e.g. the
worked example; nothing leaves the process) or running elsewhere on this host (then the
process uses the executables' host-only DDS scope so it can reach it).

A person as the oracle (``judge=``): ``judge_node`` replaces ``oracle_node``; its page's URL
goes to ``on_url`` once the run config is known, the optimizer's ``duel_timeout_s`` defaults
to a day (people take breaks; a pending duel is never failed for being slow) and the run's
``tie_threshold`` to ``DEFAULT_TIE_THRESHOLD`` (people need a "can't tell").

Resume (``resume=BAG``): the old bag is copied into the new one first (original times), the
optimizer is rebuilt by re-feeding the recorded outcomes (``driver.rebuild``), and the run
continues with the first unanswered duel, so every duel appears exactly once.

Stopping (``stop=``, set by the first SIGINT or SIGTERM in ``localpbo run``): the loop ends,
the optimizer says ``stopped`` on the status topic, the recorder takes the last messages, a
bridged controller gets its original parameters back, the judge's page stops and the bag is
closed (complete, not finished: ``--resume`` continues it). The clean-up is bounded like a
node's (``entry.STOP_GRACE_S`` plus the bridge's ``close_timeout_s``; then every thread's
stack and exit 1). A stop before the optimizer started leaves no bag (:class:`StoppedEarly`).
"""

from __future__ import annotations

import faulthandler
import os
import sys
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any

import rclpy
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from rclpy.logging import LoggingSeverity

from localpbo_core.settings import DEFAULT_TIE_THRESHOLD
from localpbo_core.space import load_space
from localpbo_msgs_py.bag import BagWriter
from localpbo_msgs_py.topics import DUEL_OUTCOME, EPISODE_RESULT
from localpbo_ros.bagtools import copy_into, load_run
from localpbo_ros.base import SuiteNode
from localpbo_ros.dds import host_scope, in_process_scope
from localpbo_ros.driver import judged_by_person
from localpbo_ros.entry import STOP_GRACE_S
from localpbo_ros.judge_node import JudgeNode
from localpbo_ros.optimizer_node import OptimizerNode, settings_from_config
from localpbo_ros.oracle_node import OracleNode
from localpbo_ros.param_bridge_node import ParamBridgeNode
from localpbo_ros.params import ParameterError
from localpbo_ros.recorder_node import RecorderNode
from localpbo_ros.sim_node import Evaluator, SimNode
from localpbo_ros.summary import RunSummary

HUMAN_DUEL_TIMEOUT_S = 86_400.0
"""The optimizer's ``duel_timeout_s`` when a person answers (unless the settings give one)."""

STOPPED = "stopped"
"""The summary's state of a run ended by a stop request (SIGINT/SIGTERM)."""


class StoppedEarly(Exception):
    """A stop was requested before the optimizer started: nothing ran and no bag is left."""


def run_suite(
    settings: dict[str, Any],
    bag: str | os.PathLike[str],
    *,
    resume: str | os.PathLike[str] | None = None,
    record: bool = True,
    evaluator: Evaluator | None = None,
    on_progress: Callable[[int, int], None] | None = None,
    timeout_s: float | None = None,
    bridge: dict[str, Any] | None = None,
    controllers: Sequence[Callable[[Context], Any]] = (),
    judge: dict[str, Any] | None = None,
    on_url: Callable[[str], None] | None = None,
    stop: threading.Event | None = None,
) -> RunSummary:
    """Run optimizer, simulator, oracle (and recorder) until the budget is spent.

    Args:
        settings: optimizer-node parameters (see ``optimizer_node.PARAMS``); ignored except
            for the timing ones and ``speculate`` when resuming (the bag's config rules).
        bag: output ``.mcap`` path.
        resume: a bag of a stopped/crashed run to continue.
        record: run the recorder (False only for the benchmark).
        evaluator: replaces the simulator's episode (tests).
        on_progress: called with (evaluations used, budget) after each spin.
        timeout_s: give up (state ``timeout``) after this many seconds.
        bridge: ``param_bridge_node`` parameters: evaluate on a controller node through its
            parameters instead of simulating (a space run: ``settings["space"]``).
        controllers: node factories (given the context) started in this process first, e.g.
            the worked example's controller.
        judge: ``judge_node`` parameters: a person answers the duels in a browser instead of
            the simulated oracle.
        on_url: called once with the judge page's URL.
        stop: when set (``localpbo run``: by SIGINT/SIGTERM), the run stops cleanly with
            state ``stopped``; given, the clean-up is bounded by the stop watchdog.

    Raises:
        ParameterError: a refused setting (named).
        StoppedEarly: ``stop`` was set before the optimizer started (no bag is left).
    """
    if bridge is not None and not controllers:
        host_scope()  # the controller runs in another process on this host
    else:
        in_process_scope()
    start = time.monotonic()
    outcomes: tuple[Any, ...] = ()
    settings = dict(settings)
    if judge is not None:
        settings.setdefault("duel_timeout_s", HUMAN_DUEL_TIMEOUT_S)
        settings.setdefault("tie_threshold", DEFAULT_TIE_THRESHOLD)
        settings["oracle"] = "human"
    if resume is not None:
        recorded = load_run(resume)
        if judge is None and judged_by_person(recorded.config):
            raise ParameterError(
                "oracle",
                f"run {recorded.config.run_id} is judged by a person: resume it with "
                "--oracle human (judge=...), never with simulated answers",
            )
        timing = ("duel_timeout_s", "republish_period_s", "speculate")
        kept: dict[str, Any] = {k: settings[k] for k in timing if k in settings}
        settings = {**settings_from_config(recorded.config), **kept}
        outcomes = recorded.outcomes
    ctx = Context()
    rclpy.init(context=ctx)
    nodes: list[Any] = []
    writer: BagWriter | None = None
    executor = SingleThreadedExecutor(context=ctx)
    refused = False
    stopping = stop if stop is not None else threading.Event()
    try:
        if record:
            writer = BagWriter(bag)
            if resume is not None:
                copy_into(resume, writer)
            nodes.append(RecorderNode(context=ctx, writer=writer))
        nodes.extend(factory(ctx) for factory in controllers)
        if bridge is not None:
            refused = True  # a refused bridge parameter (e.g. an unknown name): no bag
            evaluator_node: Any = ParamBridgeNode(context=ctx, overrides=bridge)
            refused = False
        else:
            evaluator_node = SimNode(context=ctx, evaluator=evaluator)
        nodes.append(evaluator_node)
        oracle: OracleNode | JudgeNode
        if judge is not None:
            try:
                oracle = JudgeNode(context=ctx, overrides=judge)
            except ParameterError:
                refused = True
                raise
        else:
            oracle = OracleNode(context=ctx)
        nodes.append(oracle)
        for node in nodes:
            executor.add_node(node)
        if record:
            deadline = time.monotonic() + 10.0
            while not nodes[0].matched([EPISODE_RESULT.name, DUEL_OUTCOME.name]):
                if stopping.is_set():
                    raise StoppedEarly()
                executor.spin_once(timeout_sec=0.01)
                if time.monotonic() > deadline:
                    raise RuntimeError("recorder did not match the simulator/oracle publishers")
        settings["min_subscribers"] = 2 if record else 1
        if isinstance(evaluator_node, ParamBridgeNode) and settings.get("space"):
            refused = True  # a target that cannot take the space: no run, no bag
            evaluator_node.check_target_now(
                load_space(settings["space"]), lambda: _spin_unless_stopped(executor, stopping)
            )
            refused = False
        if stopping.is_set():
            raise StoppedEarly()
        try:
            opt = OptimizerNode(context=ctx, overrides=settings, resume_outcomes=outcomes)
        except ParameterError:
            refused = True
            raise
        # the command shows its own progress bar and summary: the node logs warnings only
        opt.get_logger().set_level(LoggingSeverity.WARN)
        nodes.append(opt)
        executor.add_node(opt)
        budget = opt.driver.session.budget
        url = ""
        while not opt.finished:
            if stopping.is_set():
                _halt(opt, STOPPED, _stop_reason(stopping, bag))
                break
            executor.spin_once(timeout_sec=0.05)
            if isinstance(oracle, JudgeNode) and oracle.state == "failed":
                opt.error, opt.state = "judge_node cannot serve the run (see its log)", "failed"
                opt.finished = True  # publishes nothing more
                break
            if isinstance(oracle, JudgeNode) and oracle.url != url:
                url = oracle.url
                if on_url is not None and url:
                    on_url(url)
            if on_progress is not None:
                on_progress(opt.driver.session.evaluations, budget)
            if timeout_s is not None and time.monotonic() - start > timeout_s:
                _halt(opt, "timeout", f"no result within {timeout_s} s")
                break
        for node in nodes:  # every node's final counters in the bag, also after a short run
            if isinstance(node, SuiteNode) and node is not opt:
                node.publish_status()
        # let the recorder take the last messages (final outcome, incumbent, status), and a
        # judge's page learn that the run is complete
        settle = time.monotonic() + (0.3 if judge is None else 1.5)  # the page sees the end
        while time.monotonic() < settle:
            executor.spin_once(timeout_sec=0.02)
    except StoppedEarly:
        refused = True  # nothing ran: no bag
        raise
    finally:
        if stop is not None:  # bounded, like a node's clean-up
            grace = STOP_GRACE_S + sum(
                n.close_timeout_s for n in nodes if isinstance(n, ParamBridgeNode)
            )
            # to the process's own stderr (a test's capture has no file descriptor)
            stderr = sys.__stderr__ if sys.__stderr__ is not None else sys.stderr
            faulthandler.dump_traceback_later(grace, exit=True, file=stderr)
        for node in nodes:
            if isinstance(node, ParamBridgeNode | JudgeNode):
                node.close()  # the controller gets its original parameters back; the page stops
        for node in nodes:
            executor.remove_node(node)
            node.destroy_node()
        executor.shutdown()
        if writer is not None:
            writer.close()
            if refused:  # nothing ran: leave no empty bag behind
                Path(bag).unlink(missing_ok=True)
        rclpy.shutdown(context=ctx)
        if stop is not None:
            faulthandler.cancel_dump_traceback_later()
    # the summary after the clean-up: its recommendation fits the model to every duel (seconds
    # on a loaded machine), which must not delay the bag and the controller's parameters
    node_summary = opt.summary()
    return replace(
        node_summary,
        wall_seconds=time.monotonic() - start,
        bag=str(bag) if record else "",
        messages_recorded=nodes[0].recorded if record else 0,
        recommended_return=_return_of(oracle, node_summary.recommended_id),
        incumbent_return=_return_of(oracle, node_summary.incumbent_id),
        first_candidate_return=oracle.episode_return(0),
    )


def _halt(opt: OptimizerNode, state: str, reason: str) -> None:
    """End the optimizer's run from outside (a stop request, the command's timeout): no more
    work is published, and its last status says why (the recorder takes it)."""
    opt.driver.cancel_speculation()
    opt.finished = True
    opt.finished_at = time.monotonic()
    opt.error, opt.state = reason, state
    opt.publish_status(1, f"{state}: {reason}")


def _stop_reason(stop: threading.Event, bag: str | os.PathLike[str]) -> str:
    name = getattr(stop, "signal_name", "") or "stop requested"
    return f"{name}; continue it with: localpbo run --resume {bag}"


def _spin_unless_stopped(executor: SingleThreadedExecutor, stopping: threading.Event) -> None:
    if stopping.is_set():
        raise StoppedEarly()
    executor.spin_once(timeout_sec=0.01)


def _return_of(oracle: OracleNode | JudgeNode, candidate_id: int | None) -> float | None:
    return None if candidate_id is None else oracle.episode_return(candidate_id)


def default_bag(out: str | os.PathLike[str], run_id: str) -> Path:
    """``OUT/<run_id>.mcap`` (the directory is created)."""
    folder = Path(out)
    folder.mkdir(parents=True, exist_ok=True)
    return folder / f"{run_id}.mcap"
