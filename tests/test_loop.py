"""The in-process loop (localpbo_core.loop): records, seeds, timing, and no f_true leak."""

from __future__ import annotations

import inspect

import numpy as np
import pytest

import localpbo_core.loop as loop_mod
from localpbo_core import make_optimizer
from localpbo_core.loop import RESULT_COLUMNS, episode_seed, run_loop
from localpbo_core.optimizers import Outcome


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
        self._watch()
        self.calls.append(("eval", seed))
        if self.clock is not None:
            self.clock.now += 100.0  # episodes must not count as decision time
        return self.true_value(theta) + 0.01 * np.random.default_rng(seed).standard_normal()


class RecordingOracle:
    def __init__(self) -> None:
        self.pairs: list[tuple[float, float]] = []

    def compare(self, value_a: float, value_b: float) -> bool:
        self.pairs.append((value_a, value_b))
        return value_a > value_b


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
    opt = TimedOptimizer(make_optimizer("sobol", 3, seed=2, budget=12, batch_size=2), clock)
    oracle = RecordingOracle()
    recs = run_loop(prob, opt, oracle, seed=7)
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
    # the oracle saw the stored evaluation values of the dueled candidates
    thetas = [c.theta for c in opt.history.candidates]
    vals = [
        float(-np.sum((t - 0.3) ** 2)) + 0.01 * np.random.default_rng(s).standard_normal()
        for t, s in zip(thetas, seeds, strict=True)
    ]
    expected = [(vals[d.first], vals[d.second]) for d in opt.history.duels]
    assert oracle.pairs == expected
    assert set(RESULT_COLUMNS) == set(recs[0].__dataclass_fields__)


@pytest.mark.parametrize("name", ["sobol", "turpbo"])
def test_no_optimizer_code_ever_touches_the_problem(name: str) -> None:
    prob = TinyProblem()
    opt = make_optimizer(name, 3, seed=0, budget=8)
    run_loop(prob, opt, RecordingOracle(), seed=0)
    assert prob.calls
    assert not [f for f in prob.callers if "localpbo_core/optimizers" in f]
    assert any(f.endswith("localpbo_core/loop.py") for f in prob.callers)


def test_dim_mismatch_is_rejected() -> None:
    with pytest.raises(ValueError, match="dim"):
        run_loop(TinyProblem(), make_optimizer("sobol", 4, seed=0), RecordingOracle(), seed=0)
