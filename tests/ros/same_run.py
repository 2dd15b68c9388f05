"""One small run recorded on two paths, read back the same way: ``localpbo bench``'s run
file and a run's bag give its candidates (native θ), episode returns and answers by duel id,
so a test can compare them exactly."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from localpbo_ros.bagtools import load_run

from localpbo_core.bench import bench
from localpbo_core.run_documents import run_file_name
from localpbo_core.settings import RunSettings
from localpbo_msgs_py import EpisodeResult
from localpbo_msgs_py.bag import read_messages
from localpbo_msgs_py.records import OutcomeKind
from localpbo_msgs_py.topics import EPISODE_RESULT

TASK = "swimmer"
TASK_OPTIONS: dict[str, object] = {"episode_steps": 60, "value_range": 50.0}
ALGORITHM = "turpbo"
OPTIONS = {"batch_size": 2}
SEED = 5
BUDGET = 12
NOISE = 0.2

Answer = tuple[int, int, str, int | None]  # first, second, kind, winner


def from_bench(
    tmp_path: Path, tie_threshold: float = 0.0, indifference: float = 0.0
) -> dict[str, Any]:
    """``native``, ``values`` and ``answers`` by id of the run made by ``localpbo bench``."""
    out = tmp_path / "bench"
    bench(
        TASK,
        [ALGORITHM],
        [SEED],
        out,
        budget=BUDGET,
        noise=NOISE,
        options={ALGORITHM: dict(OPTIONS)},
        problem_options=TASK_OPTIONS,
        progress=False,
        tie_threshold=tie_threshold,
        indifference=indifference,
    )
    name = run_file_name(RunSettings(algorithm=ALGORITHM, problem=TASK, seed=SEED))
    doc = json.loads((out / "runs" / name).read_text())
    return {
        "native": {c["id"]: tuple(c["native"]) for c in doc["candidates"]},
        "values": {c["id"]: c["value"] for c in doc["candidates"]},
        "answers": {
            a["duel_id"]: (a["first"], a["second"], a["kind"], a["winner"]) for a in doc["answers"]
        },
    }


def answers_of(bag: Path) -> dict[int, Answer]:
    """Answers by duel id as recorded (the first outcome of each duel; none failed)."""
    answers: dict[int, Answer] = {}
    for out in load_run(bag).outcomes:
        assert out.kind is not OutcomeKind.FAILED
        answers.setdefault(
            out.duel_id, (out.first_id, out.second_id, out.kind.value, out.winner_id)
        )
    return answers


def from_bag(bag: Path) -> dict[str, Any]:
    """The same three things as :func:`from_bench`, as recorded in a bag."""
    run = load_run(bag)
    values: dict[int, float | None] = {}
    for rec in read_messages(bag, topics=[EPISODE_RESULT.name]):
        res = EpisodeResult.decode(rec.message)
        assert isinstance(res, EpisodeResult)
        values.setdefault(res.candidate_id, res.episode_return)
    return {
        "native": {cid: c.theta for cid, c in run.candidates.items()},
        "values": values,
        "answers": answers_of(bag),
    }
