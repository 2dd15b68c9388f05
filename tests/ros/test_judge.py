"""judge_node without a browser: the answer rules (JudgeCore), the journal, and the web server's
HTTP paths (secret, refusals, rollouts), on a private context."""

from __future__ import annotations

import http.client
import json
import socket
import time
import urllib.error
import urllib.request
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest
from localpbo_ros.bagtools import judged_by
from localpbo_ros.judge import MAX_BODY_BYTES, Journal, JudgeCore, tie_threshold_of
from localpbo_ros.judge_node import JudgeNode, check_host
from localpbo_ros.params import ParameterError

from localpbo_msgs_py import (
    CandidateMsg,
    DuelOutcome,
    DuelRequest,
    EpisodeResult,
    OutcomeKind,
    RunConfig,
    Status,
)
from localpbo_msgs_py.topics import (
    CANDIDATE,
    DUEL_OUTCOME,
    DUEL_REQUEST,
    EPISODE_RESULT,
    RUN_CONFIG,
    STATUS,
)
from tests.ros.configs import run_config

CONFIG = run_config(
    run_id="judge-unit",
    algorithm="sobol",
    task="swimmer",
    budget=6,
    task_options={"episode_steps": 50, "value_range": 50.0},
)


class Clock:
    def __init__(self) -> None:
        self.t = 100.0

    def __call__(self) -> float:
        return self.t


def make_core(tmp_path: Path, config: RunConfig = CONFIG) -> tuple[JudgeCore, list, list, Clock]:
    published: list[DuelOutcome] = []
    dropped: list[tuple[str, str]] = []
    clock = Clock()
    core = JudgeCore(published.append, lambda r, d: dropped.append((r, d)), clock=clock)
    core.adopt(config, Journal(tmp_path / config.run_id), "s" * 32, simulated=True)
    return core, published, dropped, clock


def open_duel(core: JudgeCore, duel_id: int, first: int, second: int, *, results: bool = True):
    run = core.config.run_id
    for cid in (first, second):
        core.on_candidate(CandidateMsg(run, cid, (0.1,) * core.config.dim))
        if results:
            core.on_result(EpisodeResult.ok(run, cid, float(cid)))
    assert core.on_request(DuelRequest(run, duel_id, first, second)) is None


def body(**kw: Any) -> bytes:
    return json.dumps({"duel_id": 0, "first_id": 0, "second_id": 1, "choice": "a", **kw}).encode()


# ---------------------------------------------------------------------------- JudgeCore
def test_answer_is_journaled_published_and_timed(tmp_path: Path) -> None:
    core, published, _, clock = make_core(tmp_path)
    open_duel(core, 0, 0, 1)
    view = core.view()
    assert view["duel"]["duel_id"] == 0 and view["duel"]["ready"]
    clock.t += 7.5
    reply = core.answer(body(choice="b"))
    assert reply.status == 200 and reply.body["answer"] == "B better"
    assert published == [
        DuelOutcome("judge-unit", 0, 0, 1, OutcomeKind.DECISIVE, 1, 0, answer_seconds=7.5)
    ]
    loaded, bad = Journal(tmp_path / "judge-unit").load("judge-unit")
    assert loaded == published and bad == 0
    assert core.view()["duel"] is None and core.view()["history"][0]["answer"] == "B better"


def test_answer_goes_out_again_only_for_a_later_repeated_request(tmp_path: Path) -> None:
    core, published, _, clock = make_core(tmp_path)
    open_duel(core, 0, 0, 1)
    assert core.answer(body()).status == 200
    request = DuelRequest("judge-unit", 0, 0, 1)
    clock.t += 0.5  # re-published by the optimizer before it got the answer
    assert core.on_request(request) is None
    clock.t += 1.0  # still asked: the answer was lost (e.g. the optimizer restarted)
    assert core.on_request(request) == published[0]
    assert core.counters["requests_while_answer_in_flight"] == 1
    assert core.counters["outcomes_repeated"] == 1


def test_answer_not_journaled_is_not_recorded(tmp_path: Path) -> None:
    core, published, dropped, _ = make_core(tmp_path)
    open_duel(core, 0, 0, 1)
    (tmp_path / "judge-unit" / "answers.jsonl").mkdir()  # the journal cannot be written
    reply = core.answer(body())
    assert (reply.status, reply.reason) == (500, "journal_failed")
    assert published == [] and core.view()["duel"]["duel_id"] == 0  # still open
    assert dropped[-1][0] == "http_journal_failed"
    (tmp_path / "judge-unit" / "answers.jsonl").rmdir()
    assert core.answer(body()).status == 200 and len(published) == 1


def test_first_answer_wins_second_gets_409(tmp_path: Path) -> None:
    core, published, dropped, _ = make_core(tmp_path)
    open_duel(core, 0, 0, 1)
    assert core.answer(body(choice="a")).status == 200
    second = core.answer(body(choice="b"))
    assert second.status == 409 and second.reason == "already_answered"
    assert "A better" in second.body["detail"]
    assert len(published) == 1 and dropped[-1][0] == "http_already_answered"


@pytest.mark.parametrize(
    ("raw", "field", "reason"),
    [
        (b"{not json", "body", "bad_json"),
        (b"[1, 2]", "body", "bad_json"),
        (b'{"duel_id": NaN}', "body", "bad_json"),
        (b"\xff\xfe", "body", "bad_json"),
        (b"x" * (MAX_BODY_BYTES + 1), "body", "too_large"),
        (body(choice="c"), "choice", "unknown_choice"),
        (body(choice=1), "choice", "unknown_choice"),
        (body(duel_id=7), "duel_id", "unknown_duel"),
        (body(first_id=1, second_id=0), "first_id", "wrong_candidates"),
        (body(duel_id=True), "duel_id", "wrong_type"),
        (body(first_id=-1), "first_id", "wrong_type"),
        (body(second_id="1"), "second_id", "wrong_type"),
        (body(extra=1), "extra", "unexpected"),
        (json.dumps({"duel_id": 0, "first_id": 0, "second_id": 1}).encode(), "choice", "missing"),
        (body(choice="tie"), "choice", "ties_disabled"),
    ],
)
def test_malformed_answers_refused_with_field_and_reason(
    tmp_path: Path, raw: bytes, field: str, reason: str
) -> None:
    core, published, dropped, _ = make_core(tmp_path)
    open_duel(core, 0, 0, 1)
    reply = core.answer(raw)
    assert (reply.status, reply.body["field"], reply.body["reason"]) == (400, field, reason)
    assert published == [] and dropped == [(f"http_{reason}", reply.body["detail"])]
    assert core.answer(body()).status == 200  # the duel is still open


def test_not_ready_until_both_results(tmp_path: Path) -> None:
    core, published, _, _ = make_core(tmp_path)
    open_duel(core, 0, 0, 1, results=False)
    core.on_result(EpisodeResult.ok("judge-unit", 0, 1.0))
    duel = core.view()["duel"]
    assert not duel["ready"] and duel["a"]["result"] == "done" and duel["evaluating"] == "B"
    # a worker's heartbeat names the candidate it evaluates
    core.on_status(Status("judge-unit", "sim_node", "running", info={"worker": "w", "busy": "1"}))
    assert core.view()["duel"]["b"]["result"] == "evaluating"
    assert core.answer(body()).reason == "not_ready"
    core.on_result(EpisodeResult.ok("judge-unit", 1, 2.0))
    assert core.view()["duel"]["ready"] and core.answer(body()).status == 200
    assert len(published) == 1


def test_skip_moves_the_duel_back_and_the_next_ready_one_shows(tmp_path: Path) -> None:
    core, _, _, _ = make_core(tmp_path)
    open_duel(core, 0, 0, 1)
    open_duel(core, 1, 0, 2)
    assert core.view()["duel"]["duel_id"] == 0
    reply = core.answer(body(choice="skip"))
    assert reply.status == 200 and reply.body == {"ok": True, "skipped": 0, "alone": False}
    assert core.view()["duel"]["duel_id"] == 1
    assert core.answer(body(duel_id=1, second_id=2, choice="a")).status == 200
    again = core.view()["duel"]
    assert again["duel_id"] == 0 and again["skips"] == 1 and again["others_open"] == 0
    assert core.answer(body(choice="skip")).body["alone"] is True
    assert core.view()["duel"]["duel_id"] == 0  # alone: shown again


def test_failed_episode_fails_its_duels(tmp_path: Path) -> None:
    core, _, _, _ = make_core(tmp_path)
    open_duel(core, 0, 0, 1, results=False)
    failed = core.on_result(EpisodeResult.failed("judge-unit", 1, "boom"))
    assert [o.kind for o in failed] == [OutcomeKind.FAILED] and "boom" in failed[0].reason
    assert core.view()["duel"] is None
    open_duel(core, 0, 0, 1)  # the retry waits for the fresh results
    assert core.view()["duel"]["ready"]


def test_restart_keeps_answers_and_repeats_them_for_repeated_requests(tmp_path: Path) -> None:
    core, published, _, _ = make_core(tmp_path)
    open_duel(core, 0, 0, 1)
    assert core.answer(body(choice="b")).status == 200
    with (tmp_path / "judge-unit" / "answers.jsonl").open("a") as fh:
        fh.write('{"duel_id": 3, "first_')  # a line cut off by a crash
    again, published2, dropped2, _ = make_core(tmp_path)
    assert again.counters["journal_unreadable_lines"] == 1
    stored = again.on_request(DuelRequest("judge-unit", 0, 0, 1))
    assert stored == published[0]  # published again, never asked again
    assert again.view()["duel"] is None and again.view()["progress"]["answered"] == 1
    assert again.on_request(DuelRequest("judge-unit", 0, 0, 2)) is None
    assert dropped2 == [("conflicting_request", "duel 0 changed its candidates")]
    assert published2 == []


def test_journal_of_another_run_with_the_same_id_refused(tmp_path: Path) -> None:
    core, _, _, _ = make_core(tmp_path)
    open_duel(core, 0, 0, 1)
    assert core.answer(body()).status == 200
    other = run_config(
        run_id="judge-unit",
        algorithm="sobol",
        task="swimmer",
        budget=6,
        seed=9,
        task_options={"episode_steps": 50, "value_range": 50.0},
    )
    fresh = JudgeCore(lambda o: None, lambda r, d: None)
    with pytest.raises(ValueError, match="another run with id 'judge-unit'"):
        fresh.adopt(other, Journal(tmp_path / "judge-unit"), "s" * 32, simulated=True)
    assert fresh.config is None
    same = JudgeCore(lambda o: None, lambda r, d: None)  # the same run (resumed): accepted
    assert same.adopt(CONFIG, Journal(tmp_path / "judge-unit"), "s" * 32, simulated=True) == 1


def test_secret_kept_per_run_folder(tmp_path: Path) -> None:
    journal = Journal(tmp_path / "r")
    first = journal.secret(lambda: "A" * 32)
    assert first == "A" * 32 and Journal(tmp_path / "r").secret(lambda: "B" * 32) == first
    assert (tmp_path / "r" / "secret").stat().st_mode & 0o077 == 0
    assert Journal(tmp_path / "other").secret(lambda: "C" * 32) == "C" * 32


def test_tie_threshold_read_from_the_run_config() -> None:
    assert tie_threshold_of(CONFIG) == 0.0
    options = {**CONFIG.options, "oracle": {**CONFIG.options["oracle"], "tie_threshold": 0.5}}
    with_ties = RunConfig(
        CONFIG.run_id,
        CONFIG.algorithm,
        CONFIG.task,
        CONFIG.dim,
        CONFIG.lower,
        CONFIG.upper,
        CONFIG.seed,
        CONFIG.budget,
        options,
    )
    assert tie_threshold_of(with_ties) == 0.5


# ---------------------------------------------------------------------------- parameters
def test_host_must_be_loopback_unless_allowed() -> None:
    assert check_host("127.0.0.1", False) == "127.0.0.1"
    assert check_host("::1", False) == "::1"
    assert check_host("localhost", False) == "127.0.0.1"
    with pytest.raises(ParameterError, match=r"'host'.*allow_remote"):
        check_host("0.0.0.0", False)
    assert check_host("0.0.0.0", True) == "0.0.0.0"
    with pytest.raises(ParameterError, match=r"'host'.*not an IP"):
        check_host("example.org", True)


def test_busy_port_refused_naming_the_parameter(ros, tmp_path: Path) -> None:
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        with pytest.raises(ParameterError, match="'port'"):
            JudgeNode(context=ros.ctx, overrides={"port": port, "state_dir": str(tmp_path)})
    with pytest.raises(ParameterError, match="'port'"):
        JudgeNode(context=ros.ctx, overrides={"port": 70000, "state_dir": str(tmp_path)})
    with pytest.raises(ParameterError, match="'host'"):
        JudgeNode(context=ros.ctx, overrides={"host": "0.0.0.0", "state_dir": str(tmp_path)})


# ---------------------------------------------------------------------------- HTTP
def fetch(url: str, data: bytes | None = None) -> tuple[int, Any]:
    req = urllib.request.Request(url, data=data, headers={"Content-Type": "application/json"})
    try:
        with urllib.request.urlopen(req, timeout=10) as r:
            raw, status, kind = r.read(), r.status, r.headers.get("Content-Type", "")
    except urllib.error.HTTPError as err:
        raw, status, kind = err.read(), err.code, err.headers.get("Content-Type", "")
    return status, json.loads(raw) if kind.startswith("application/json") else raw


@pytest.fixture
def judge(ros, tmp_path: Path) -> Any:
    node = ros.add(JudgeNode(context=ros.ctx, overrides={"state_dir": str(tmp_path / "state")}))
    yield node
    node.close()


def start_run(ros, judge: JudgeNode, config: RunConfig) -> list:
    outcomes = ros.collect(DUEL_OUTCOME)
    ros.publish(RUN_CONFIG, config.encode())
    assert ros.spin_until(lambda: bool(judge.url), 5.0)
    return outcomes


def test_http_paths_secret_and_refusals(ros, judge: JudgeNode, tmp_path: Path) -> None:
    base = f"http://127.0.0.1:{judge.web.port}/"
    assert fetch(base + "anything/api/state")[0] == 404  # before the run: nothing is served
    outcomes = start_run(ros, judge, CONFIG)
    url = judge.url
    assert url.startswith(base) and (tmp_path / "state" / "url").read_text().strip() == url
    secret = url[len(base) : -1]
    assert len(secret) >= 32
    # wrong secret: 404 and counted
    status, _ = fetch(base + "x" * len(secret) + "/api/state")
    assert status == 404 and judge.counters["dropped_wrong_secret"] >= 1
    status, page = fetch(url)
    assert status == 200 and b"Which was better?" in page and b"static/judge.js" in page
    assert fetch(url + "static/judge.js")[0] == 200 and fetch(url + "static/x.js")[0] == 404
    assert fetch(url.rstrip("/"))[0] == 200  # redirected to the page
    # a duel: candidates, results, request
    run = CONFIG.run_id
    for cid in (0, 1):
        ros.publish(CANDIDATE, CandidateMsg(run, cid, (0.2,) * CONFIG.dim).encode())
        ros.publish(EPISODE_RESULT, EpisodeResult.ok(run, cid, float(cid)).encode())
    ros.publish(DUEL_REQUEST, DuelRequest(run, 0, 0, 1).encode())
    assert ros.spin_until(lambda: (judge.core.view()["duel"] or {}).get("ready", False), 5.0)
    status, state = fetch(url + "api/state")
    assert status == 200 and state["duel"]["ready"] and state["run"]["names"][0].startswith("W[")
    # malformed answers: 400 with field and reason, nothing published
    answer = url + "api/answer"
    for _ in range(2):
        status, reply = fetch(answer, b"{oops")
        assert (status, reply["field"], reply["reason"]) == (400, "body", "bad_json")
    status, reply = fetch(answer, body(choice="maybe"))
    assert (status, reply["field"], reply["reason"]) == (400, "choice", "unknown_choice")
    conn = http.client.HTTPConnection("127.0.0.1", judge.web.port, timeout=10)
    conn.putrequest("POST", f"/{secret}/api/answer")
    conn.putheader("Content-Length", str(10**9))  # refused before reading a byte
    conn.endheaders()
    resp = conn.getresponse()
    assert resp.status == 400 and json.loads(resp.read())["reason"] == "too_large"
    conn.close()
    assert fetch(url + "api/nothing")[0] == 404
    ros.spin_for(0.2)
    assert outcomes == []
    # the answer; a second one for the same duel is told who won
    status, reply = fetch(answer, body(choice="a"))
    assert status == 200 and reply["recorded"] == 0
    status, reply = fetch(answer, body(choice="b"))
    assert status == 409 and reply["reason"] == "already_answered"
    assert ros.spin_until(lambda: len(outcomes) == 1, 5.0)
    got = DuelOutcome.decode(outcomes[0])
    assert got.winner_id == 0 and got.answer_seconds is not None and got.answer_seconds >= 0
    # counted by reason on the status topic
    statuses = ros.collect(STATUS)
    assert ros.spin_until(
        lambda: any(
            s.node == "judge_node" and s.counters.get("dropped_http_bad_json") == 2
            for s in (Status.decode(m) for m in statuses)
        ),
        5.0,
    )
    seen = next(s for s in (Status.decode(m) for m in statuses) if s.node == "judge_node")
    assert seen.counters["dropped_http_too_large"] == 1
    assert seen.counters["dropped_http_already_answered"] == 1
    assert seen.counters["answers"] == 1
    assert secret not in json.dumps(seen.info)  # the secret never goes on a topic


def test_rollout_replay_api_returns_hopper_frames(ros, judge: JudgeNode) -> None:
    config = run_config(run_id="judge-hop", algorithm="sobol", task="hopper", budget=4)
    start_run(ros, judge, config)
    theta = tuple(0.5 * (lo + hi) for lo, hi in zip(config.lower, config.upper, strict=True))
    ros.publish(CANDIDATE, CandidateMsg(config.run_id, 3, theta).encode())
    assert ros.spin_until(lambda: 3 in judge.core.candidates, 5.0)
    status, rollout = fetch(judge.url + "api/rollout/3")
    assert status == 200
    assert rollout["axes"] == ["x", "z"] and rollout["geoms"][0] == "torso_geom"
    assert rollout["frame_steps"][-1] == rollout["steps"] and rollout["stride"] == 4
    assert len(rollout["frames"]) == len(rollout["frame_steps"])
    assert all(len(frame) == 4 and len(frame[0]) == 4 for frame in rollout["frames"])
    # the very episode the simulator scores: same seed, same θ
    from localpbo_ros.driver import problem_of

    from localpbo_core.seeds import episode_seed

    task = problem_of(config)
    weights = np.asarray(theta).reshape(task.action_dim, task.obs_dim)
    plain = task.rollout_weights(weights, episode_seed(config.seed, 3))
    assert rollout["steps"] == plain.steps and rollout["terminated"] == plain.terminated
    assert fetch(judge.url + "api/rollout/9")[0] == 404  # unknown candidate
    assert fetch(judge.url + "api/rollout/abc")[0] == 404


def test_connections_beyond_the_limit_are_closed_and_counted(ros, tmp_path: Path) -> None:
    node = ros.add(
        JudgeNode(context=ros.ctx, overrides={"state_dir": str(tmp_path), "max_connections": 1})
    )
    try:
        start_run(ros, node, CONFIG)
        with socket.create_connection(("127.0.0.1", node.web.port)) as idle:  # holds the slot
            time.sleep(0.2)
            with pytest.raises((urllib.error.URLError, ConnectionError, http.client.HTTPException)):
                fetch(node.url + "api/state")
            assert node.counters["dropped_http_busy"] == 1
            idle.sendall(b"GET /nope HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n")
            assert b"404" in idle.recv(100)
        served = False  # the slot is free again once the held connection's thread ends
        until_free = time.monotonic() + 5
        while not served and time.monotonic() < until_free:
            try:
                served = fetch(node.url + "api/state")[0] == 200
            except (urllib.error.URLError, ConnectionError, http.client.HTTPException):
                time.sleep(0.05)
        assert served
    finally:
        node.close()


def test_the_optimizers_recommendation_is_shown(tmp_path: Path) -> None:
    core, _, _, _ = make_core(tmp_path)
    assert core.view()["recommended"] is None
    open_duel(core, 0, 0, 1)
    core.on_status(Status("judge-unit", "optimizer_node", "running", info={"recommended": "1"}))
    rec = core.view()["recommended"]
    assert rec["id"] == 1 and rec["theta"] is not None and len(rec["theta"]) == CONFIG.dim
    bad = Status("judge-unit", "optimizer_node", "running", info={"recommended": "x1"})
    core.on_status(bad)  # not an id: the last good one stays
    assert core.view()["recommended"]["id"] == 1


# ---------------------------------------------------------------------------- notes, time, undo
def test_note_name_and_visible_time_journaled(tmp_path: Path) -> None:
    core, published, _, clock = make_core(tmp_path)
    open_duel(core, 0, 0, 1)
    core.view()
    clock.t += 30.0  # 30 s since the judge showed it; the page was visible for 4 s of them
    extra = {"note": " steadier ", "judge": "Ada", "visible_seconds": 4.0, "hidden": True}
    assert core.answer(body(**extra)).status == 200
    assert published[0].answer_seconds == 4.0
    # the name and the note go into the run's record (the outcome the bag keeps) too
    assert (published[0].judge, published[0].note) == ("Ada", "steadier")
    assert DuelOutcome.decode(published[0].encode()) == published[0]
    line = json.loads((tmp_path / "judge-unit" / "answers.jsonl").read_text())
    assert (line["note"], line["judge"], line["hidden"]) == ("steadier", "Ada", True)
    assert line["server_seconds"] == 30.0
    entry = core.view()["history"][0]
    assert (entry["note"], entry["judge"], entry["hidden"]) == ("steadier", "Ada", True)
    # a page's claim above the judge's own clock is capped by it
    open_duel(core, 1, 0, 2)
    core.view()
    clock.t += 2.0
    assert core.answer(body(duel_id=1, second_id=2, visible_seconds=50.0)).status == 200
    assert published[1].answer_seconds == 2.0
    # a journal read back (a restarted judge) gives the same outcomes, name and note included
    reread, bad = Journal(tmp_path / "judge-unit").load("judge-unit")
    assert bad == 0 and reread == published[:2]


def test_bag_info_names_who_judged_the_answers_that_stand() -> None:
    req = [DuelRequest("r", k, 0, k + 1) for k in range(4)]
    outcomes = [
        DuelOutcome.decisive(req[0], 0, judge="Ada", note="smoother"),
        DuelOutcome.decisive(req[0], 0, judge="Ada", note="smoother"),  # re-published
        DuelOutcome.indifferent(req[1], judge="Bo"),
        DuelOutcome.decisive(req[2], 3, judge="Bo"),
        DuelOutcome.retracted(req[2]),  # Bo's answer taken back ...
        DuelOutcome.decisive(req[2], 0, judge="Ada"),  # ... and Ada's stands
        DuelOutcome.failed(req[3], "episode failed"),
    ]
    assert judged_by(SimpleNamespace(outcomes=outcomes)) == "judged by: Ada 2, Bo 1; 1 note"
    assert judged_by(SimpleNamespace(outcomes=[DuelOutcome.decisive(req[0], 0)])) == ""


@pytest.mark.parametrize(
    ("extra", "field"),
    [
        ({"note": "x" * 1001}, "note"),
        ({"note": 3}, "note"),
        ({"judge": "n" * 81}, "judge"),
        ({"visible_seconds": -1}, "visible_seconds"),
        ({"visible_seconds": True}, "visible_seconds"),
        ({"hidden": "yes"}, "hidden"),
    ],
)
def test_bad_optional_fields_refused(tmp_path: Path, extra: dict, field: str) -> None:
    core, published, _, _ = make_core(tmp_path)
    open_duel(core, 0, 0, 1)
    reply = core.answer(body(**extra))
    assert (reply.status, reply.body["field"], reply.body["reason"]) == (400, field, "wrong_type")
    assert published == []


def test_duplicate_json_keys_refused(tmp_path: Path) -> None:
    core, published, dropped, _ = make_core(tmp_path)
    open_duel(core, 0, 0, 1)
    raw = b'{"duel_id": 0, "first_id": 0, "second_id": 1, "choice": "a", "choice": "b"}'
    reply = core.answer(raw)
    assert (reply.status, reply.body["field"], reply.reason) == (400, "choice", "duplicate_key")
    assert published == [] and dropped[-1][0] == "http_duplicate_key"


def test_undo_retracts_then_the_reasked_duel_is_answered_anew(tmp_path: Path) -> None:
    core, published, _, _ = make_core(tmp_path)
    open_duel(core, 0, 0, 1)
    assert core.answer(body(choice="a")).status == 200
    open_duel(core, 1, 0, 2)  # the optimizer's next duel
    assert core.view()["undo"] == {"duel_id": 0, "answer": "A better"}
    refused = core.undo(json.dumps({"duel_id": 1}).encode())
    assert (refused.status, refused.reason) == (409, "not_latest")
    reply = core.undo(json.dumps({"duel_id": 0}).encode())
    assert reply.status == 200 and reply.body["undone"] == 0
    assert published[-1] == DuelOutcome("judge-unit", 0, 0, 1, OutcomeKind.RETRACTED)
    assert core.undo(json.dumps({"duel_id": 0}).encode()).reason == "undo_pending"
    view = core.view()
    assert view["retracting"] == [0] and view["history"][0]["undone"] == "undone"
    assert view["progress"]["answered"] == 0
    # duel 1, asked after the answer being taken back, is hidden at once and not answerable
    assert view["duel"] is None
    withdrawn = core.answer(body(duel_id=1, second_id=2))
    assert (withdrawn.status, withdrawn.reason) == (409, "withdrawn")
    # the optimizer asks duel 0 again: it opens first, the later duel 1 is withdrawn
    assert core.on_request(DuelRequest("judge-unit", 0, 0, 1)) is None
    view = core.view()
    assert view["duel"]["duel_id"] == 0 and view["progress"]["open"] == 1
    assert core.counters["duels_withdrawn"] == 1
    assert core.answer(body(choice="b")).status == 200
    assert published[-1].winner_id == 1
    # the journal: answer, undo, answer; a restarted judge stands by the last answer
    lines = (tmp_path / "judge-unit" / "answers.jsonl").read_text().splitlines()
    assert [next(iter(json.loads(x))) for x in lines] == ["duel_id", "undo", "duel_id"]
    again, _, _, _ = make_core(tmp_path)
    assert again.answered[0].winner_id == 1 and again.order == [0]


def test_refused_undo_restores_the_answer(tmp_path: Path) -> None:
    core, _, _, _ = make_core(tmp_path)
    open_duel(core, 0, 0, 1)
    assert core.answer(body(choice="a")).status == 200
    status = Status("judge-unit", "optimizer_node", "running", counters={"duels_done": 1})
    core.on_status(status)  # the optimizer's count of refusals so far: none
    assert core.undo(json.dumps({"duel_id": 0}).encode()).status == 200
    refused = Status(
        "judge-unit",
        "optimizer_node",
        "running",
        counters={"duels_done": 1, "retraction_refused": 1},
    )
    open_duel(core, 1, 0, 2)  # asked before the undo arrived: hidden while the undo is on
    assert core.view()["duel"] is None
    core.on_status(refused)
    view = core.view()
    assert view["retracting"] == [] and view["progress"]["answered"] == 1
    assert view["duel"]["duel_id"] == 1  # the undo refused: duel 1 stands, shown again
    assert "refused" in view["notice"] and view["history"][0]["undone"] == ""
    assert core.counters["undo_refused"] == 1
    again, _, _, _ = make_core(tmp_path)  # journal: answer, undo, restore
    assert 0 in again.answered and not again.retracting


def test_retraction_repeated_when_the_optimizer_asks_past_it(tmp_path: Path) -> None:
    core, _, _, clock = make_core(tmp_path)
    open_duel(core, 0, 0, 1)
    assert core.answer(body()).status == 200
    assert core.undo(json.dumps({"duel_id": 0}).encode()).status == 200
    clock.t += 2.0  # the optimizer did not get it (restarted) and asks duel 1
    again = core.on_request(DuelRequest("judge-unit", 1, 0, 2))
    assert again == DuelOutcome("judge-unit", 0, 0, 1, OutcomeKind.RETRACTED)


def test_every_change_bumps_the_version_and_wakes_waiters(tmp_path: Path) -> None:
    core, _, _, _ = make_core(tmp_path)
    before = core.version
    woke: list[int] = []

    def wait() -> None:
        with core.changed:
            core.changed.wait_for(lambda: core.version != before, timeout=5)
            woke.append(core.version)

    import threading

    waiter = threading.Thread(target=wait)
    waiter.start()
    time.sleep(0.05)
    open_duel(core, 0, 0, 1)
    waiter.join(5)
    assert woke and woke[0] > before
    settled = core.version
    core.on_status(Status("judge-unit", "optimizer_node", "running", counters={"duels_done": 0}))
    core.on_status(Status("judge-unit", "optimizer_node", "running", counters={"duels_done": 0}))
    assert core.version == settled + 1  # a heartbeat that changes nothing wakes nobody


# ---------------------------------------------------------------------------- HTTP limits
def raw_request(port: int, data: bytes, timeout: float = 10.0) -> tuple[bytes, float]:
    """Send ``data``; the reply's first bytes and how long until the server closed."""
    start = time.monotonic()
    with socket.create_connection(("127.0.0.1", port), timeout=timeout) as conn:
        conn.sendall(data)
        got = b""
        while True:
            chunk = conn.recv(65536)
            if not chunk:
                break
            got += chunk
    return got, time.monotonic() - start


def test_http_limits_414_431_408(ros, judge: JudgeNode) -> None:
    start_run(ros, judge, CONFIG)
    secret = judge.url.rstrip("/").rsplit("/", 1)[1]
    port = judge.web.port
    # a request line over 8 KiB: 414, and the connection closed
    got, _ = raw_request(port, b"GET /" + b"x" * 9000 + b" HTTP/1.1\r\nHost: x\r\n\r\n")
    assert got.startswith(b"HTTP/1.1 414") and b"line_too_long" in got
    # header lines over 8 KiB together (each line short): 431
    headers = b"".join(b"X-Pad-%d: %s\r\n" % (i, b"y" * 200) for i in range(60))
    got, _ = raw_request(
        port, b"GET /%s/api/state HTTP/1.1\r\nHost: x\r\n" % secret.encode() + headers + b"\r\n"
    )
    assert got.startswith(b"HTTP/1.1 431") and b"headers_too_large" in got
    # just below the limits: served
    headers = b"".join(b"X-Pad-%d: %s\r\n" % (i, b"y" * 100) for i in range(30))
    got, _ = raw_request(
        port,
        b"GET /%s/api/state HTTP/1.1\r\nHost: x\r\nConnection: close\r\n" % secret.encode()
        + headers
        + b"\r\n",
    )
    assert got.startswith(b"HTTP/1.1 200")
    # a body shorter than its Content-Length: 408 after BODY_TIMEOUT_S, connection closed
    from localpbo_ros.judge_web import BODY_TIMEOUT_S

    got, took = raw_request(
        port,
        b'POST /%s/api/answer HTTP/1.1\r\nHost: x\r\nContent-Length: 100\r\n\r\n{"duel'
        % secret.encode(),
    )
    assert got.startswith(b"HTTP/1.1 408") and b"body_timeout" in got
    assert BODY_TIMEOUT_S - 0.5 <= took <= BODY_TIMEOUT_S + 3.0
    for reason in ("line_too_long", "headers_too_large", "body_timeout"):
        assert judge.counters[f"dropped_http_{reason}"] == 1


def test_events_push_the_state_when_it_changes(ros, judge: JudgeNode) -> None:
    start_run(ros, judge, CONFIG)
    secret = judge.url.rstrip("/").rsplit("/", 1)[1]
    conn = http.client.HTTPConnection("127.0.0.1", judge.web.port, timeout=10)
    conn.request("GET", f"/{secret}/api/events")
    resp = conn.getresponse()
    assert resp.status == 200 and resp.headers["Content-Type"].startswith("text/event-stream")

    def next_state() -> dict:
        while True:
            line = resp.fp.readline()
            if line.startswith(b"data: "):
                return json.loads(line[6:])

    first = next_state()
    assert first["run"]["run_id"] == CONFIG.run_id and first["duel"] is None
    run = CONFIG.run_id
    for cid in (0, 1):
        ros.publish(CANDIDATE, CandidateMsg(run, cid, (0.2,) * CONFIG.dim).encode())
        ros.publish(EPISODE_RESULT, EpisodeResult.ok(run, cid, float(cid)).encode())
    ros.publish(DUEL_REQUEST, DuelRequest(run, 0, 0, 1).encode())
    seen = first
    end = time.monotonic() + 10
    while not (seen["duel"] and seen["duel"]["ready"]) and time.monotonic() < end:
        ros.spin_for(0.05)
        seen = next_state()
    assert seen["duel"]["ready"] and seen["version"] > first["version"]
    conn.close()


def test_restarted_judge_serves_on_the_runs_former_port(ros, tmp_path: Path) -> None:
    state = str(tmp_path / "state")
    first = ros.add(JudgeNode(context=ros.ctx, overrides={"state_dir": state}))
    start_run(ros, first, CONFIG)
    url, port = first.url, first.web.port
    first.close()
    ros.remove(first)
    second = ros.add(JudgeNode(context=ros.ctx, overrides={"state_dir": state}))
    try:
        ros.publish(RUN_CONFIG, CONFIG.encode())
        assert ros.spin_until(lambda: bool(second.url), 5.0)
        assert second.url == url and second.web.port == port
        assert fetch(url + "api/state")[0] == 200
    finally:
        second.close()
