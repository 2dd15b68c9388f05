"""The in-process run (localpbo_core.loop.run_session): records, seeds, timing, no f_true leak."""

from __future__ import annotations

import inspect

import numpy as np
import pytest

import localpbo_core.loop as loop_mod
import localpbo_core.session as session_mod
from localpbo_core.loop import RESULT_COLUMNS, run_session
from localpbo_core.optimizers import Outcome
from localpbo_core.seeds import episode_seed
from localpbo_core.session import RunSettings, Session, SettingError


class Clock:
    def __init__(self) -> None:
        self.now = 0.0

    def __call__(self) -> float:
        return self.now


class TinyProblem:
    """Quadratic on [0,1]^3 whose episode value depends on the seed; watches its callers."""

    name = "tiny"
    dim = 3
    value_range = 1.0

    def __init__(self, clock: Clock | None = None) -> None:
        self.clock = clock
        self.calls: list[tuple[str, int | None]] = []
        self.callers: set[str] = set()

    def _watch(self) -> None:
        for frame in inspect.stack()[2:]:
            self.callers.add(frame.filename)

    def to_native(self, theta: np.ndarray) -> np.ndarray:
        return theta

    def true_value(self, theta: np.ndarray) -> float:
        self._watch()
        self.calls.append(("true", None))
        return float(-np.sum((theta - 0.3) ** 2))

    def evaluate(self, theta: np.ndarray, seed: int) -> float:
        return self.evaluate_native(self.to_native(theta), seed)

    def evaluate_native(self, x: np.ndarray, seed: int) -> float:
        self._watch()
        self.calls.append(("eval", seed))
        if self.clock is not None:
            self.clock.now += 100.0  # episodes must not count as decision time
        return float(-np.sum((x - 0.3) ** 2)) + 0.01 * np.random.default_rng(seed).standard_normal()


class RecordingOracle:
    def __init__(self) -> None:
        self.pairs: list[tuple[int, float, float]] = []

    def judge(self, duel_id: int, value_a: float, value_b: float) -> bool | None:
        self.pairs.append((duel_id, value_a, value_b))
        return value_a > value_b


def tiny_session(algorithm: str, seed: int, budget: int, problem: TinyProblem, **options):
    settings = RunSettings(
        algorithm=algorithm, problem="tiny", seed=seed, budget=budget, optimizer_options=options
    )
    return Session(settings, problem)


class TimedOptimizer:
    """Wraps an optimizer; ask costs 1 s and tell 2 s on the fake clock; checks tell input."""

    def __init__(self, opt, clock: Clock) -> None:
        self.opt, self.clock = opt, clock
        self.asks = 0

    def __getattr__(self, item):
        return getattr(self.opt, item)

    def ask(self):
        self.clock.now += 1.0
        self.asks += 1
        return self.opt.ask()

    def tell(self, outcomes):
        outcomes = list(outcomes)
        assert all(type(o) is Outcome for o in outcomes)
        self.clock.now += 2.0
        return self.opt.tell(outcomes)


def test_records_metrics_seeds_and_decision_time(monkeypatch: pytest.MonkeyPatch) -> None:
    clock = Clock()
    monkeypatch.setattr(loop_mod.time, "perf_counter", clock)
    prob = TinyProblem(clock)
    session = tiny_session("sobol", 7, 12, prob, batch_size=2)
    opt = TimedOptimizer(session.optimizer, clock)
    session.optimizer = opt  # type: ignore[assignment]
    oracle = RecordingOracle()
    monkeypatch.setattr(session, "oracle", lambda: oracle)
    recs = run_session(session).records
    assert len(recs) == 12
    assert [r.evaluation for r in recs] == list(range(1, 13))
    assert [r.candidate_id for r in recs] == list(range(12))
    f = np.array([r.f_true for r in recs])
    np.testing.assert_allclose([r.best_seen for r in recs], np.maximum.accumulate(f))
    np.testing.assert_allclose([r.cumulative for r in recs], np.cumsum(f))
    # optimizer time only (3 s per ask), split over the candidates of each ask
    assert sum(r.decision_seconds for r in recs) == pytest.approx(3.0 * opt.asks)
    assert recs[0].decision_seconds == pytest.approx(1.5)  # first ask: 2 candidates
    # each candidate evaluated exactly once with its derived seed
    seeds = [s for k, s in prob.calls if k == "eval"]
    assert seeds == [episode_seed(7, i) for i in range(12)]
    assert len(set(seeds)) == 12
    assert episode_seed(7, 0) != episode_seed(8, 0)
    # the oracle saw the stored evaluation values of the dueled candidates, by duel id
    thetas = [c.theta for c in opt.history.candidates]
    vals = [
        float(-np.sum((t - 0.3) ** 2)) + 0.01 * np.random.default_rng(s).standard_normal()
        for t, s in zip(thetas, seeds, strict=True)
    ]
    expected = [(k, vals[d.first], vals[d.second]) for k, d in enumerate(opt.history.duels)]
    assert oracle.pairs == expected
    assert set(RESULT_COLUMNS) == set(recs[0].__dataclass_fields__)


@pytest.mark.parametrize("name", ["sobol", "turpbo"])
def test_no_optimizer_code_ever_touches_the_problem(name: str) -> None:
    prob = TinyProblem()
    run_session(tiny_session(name, 0, 8, prob))
    assert prob.calls
    assert not [f for f in prob.callers if "localpbo_core/optimizers" in f]
    assert any(f.endswith("localpbo_core/session.py") for f in prob.callers)


def test_answers_of_an_ask_are_told_in_duel_order_whatever_the_arrival_order() -> None:
    """The session buffers the answers of an ask and tells them by duel id."""
    runs = []
    for reverse in (False, True):
        session = tiny_session("sobol", 3, 10, TinyProblem(), batch_size=3)
        oracle = session.oracle()
        values: dict[int, float] = {}
        while not session.done:
            step = session.ask()
            for cand in step.candidates:
                values[cand.id] = session.evaluate(cand)
            duels = list(reversed(step.duels)) if reverse else list(step.duels)
            for duel in duels:
                first = oracle.first_wins(duel.duel_id, values[duel.first], values[duel.second])
                winner = duel.first if first else duel.second
                assert session.offer(session_mod.Answer.decisive(duel, winner)).accepted
        runs.append(session.optimizer.history)
    assert runs[0].outcomes == runs[1].outcomes
    assert [c.theta.tobytes() for c in runs[0].candidates] == [
        c.theta.tobytes() for c in runs[1].candidates
    ]


def test_settings_errors_name_their_field() -> None:
    with pytest.raises(SettingError) as err:
        tiny_session("sobol", 0, 10, TinyProblem(), batch_size=0)
    assert err.value.field == "optimizer_options.batch_size"
    with pytest.raises(SettingError) as err:
        tiny_session("sobol", 0, 10, TinyProblem(), no_such_option=1)
    assert err.value.field == "optimizer_options.no_such_option"
    with pytest.raises(SettingError) as err:
        RunSettings(algorithm="sobol", problem="tiny", noise_fraction=-1.0)
    assert (err.value.field, err.value.reason) == (
        "noise_fraction",
        "must lie in [0, inf), got -1.0",
    )
    with pytest.raises(SettingError) as err:
        Session(RunSettings(algorithm="nope", problem="hartmann6"))
    assert err.value.field == "algorithm"
    with pytest.raises(SettingError) as err:
        Session(RunSettings(algorithm="sobol", problem="nope"))
    assert err.value.field == "problem"
