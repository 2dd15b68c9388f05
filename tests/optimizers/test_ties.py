"""Every algorithm runs on "can't tell" answers (all of them, or a mix) and repeats exactly."""

from __future__ import annotations

import numpy as np
import pytest

from localpbo_core import Indifferent, InvalidOutcome, Outcome, make_optimizer
from localpbo_core.problems import make_problem
from localpbo_core.session import Answer, AnswerKind, Reason, RunSettings, Session

ALGORITHMS = ["sobol", "turpbo", "prefsqp", "gipbor", "gipbo", "qeubo", "glisp", "hbei"]
_FAST = {
    "turpbo": {"num_raw_samples": 64, "num_features": 128},
    "qeubo": {"num_raw_samples": 32, "num_restarts": 2},
    "hbei": {"num_raw_samples": 64, "burn_in": 200, "steps_per_iteration": 50},
    "glisp": {"pso_iters": 50},
}


def _run(algorithm: str, mode: str) -> tuple[list[np.ndarray], int]:
    problem = make_problem("hartmann6")
    opt = make_optimizer(
        algorithm, dim=6, seed=1, budget=16, tie_threshold=0.5, **_FAST.get(algorithm, {})
    )
    values: dict[int, float] = {}
    while not opt.done:
        ask = opt.ask()
        for c in ask.candidates:
            values[c.id] = problem.true_value(c.theta)
        outs: list[Outcome | Indifferent] = []
        for d in ask.duels:
            a, b = values[d.first], values[d.second]
            if mode == "all" or abs(a - b) < 0.3:
                outs.append(Indifferent(d.first, d.second))
            else:
                outs.append(Outcome(d.first, d.second) if a > b else Outcome(d.second, d.first))
        opt.tell(outs)
    thetas = [c.theta for c in opt.history.candidates]
    assert len(thetas) == 16 and all(np.isfinite(t).all() for t in thetas)
    return thetas, len(opt.ties())


@pytest.mark.parametrize("algorithm", ALGORITHMS)
@pytest.mark.parametrize("mode", ["all", "mix"])
def test_runs_on_ties_and_repeats(algorithm: str, mode: str) -> None:
    first, n_ties = _run(algorithm, mode)
    assert n_ties >= (15 if mode == "all" else 1)
    again, _ = _run(algorithm, mode)
    assert all(np.array_equal(a, b) for a, b in zip(first, again, strict=True))


def test_tie_keeps_the_incumbent_and_needs_a_threshold() -> None:
    opt = make_optimizer("sobol", dim=2, seed=0, budget=4, tie_threshold=0.3)
    ask = opt.ask()
    opt.tell([Indifferent(ask.duels[0].first, ask.duels[0].second)])
    assert opt.incumbent is not None and opt.incumbent.id == 0  # the earlier candidate
    ask = opt.ask()
    opt.tell([Indifferent(ask.duels[0].first, ask.duels[0].second)])
    assert opt.incumbent.id == 0 and opt.ties().tolist() == [[1, 0], [2, 0]]
    plain = make_optimizer("sobol", dim=2, seed=0, budget=4)
    d = plain.ask().duels[0]
    with pytest.raises(InvalidOutcome) as info:
        plain.tell([Indifferent(d.first, d.second)])
    assert info.value.field == "outcome"


@pytest.mark.parametrize("threshold", [0.0, 0.5])
def test_session_accepts_indifferent_iff_threshold(threshold: float) -> None:
    s = Session(RunSettings("sobol", "hartmann6", budget=4, tie_threshold=threshold))
    duel = s.ask().duels[0]
    verdict = s.offer(Answer.indifferent(duel))
    if threshold > 0:
        assert verdict.accepted and s.optimizer.ties().shape == (1, 2)
    else:
        assert verdict.reason is Reason.UNSUPPORTED_KIND and s.step_open


def test_settings_refuse_a_tie_oracle_without_threshold() -> None:
    from localpbo_core.settings import SettingError

    with pytest.raises(SettingError) as info:
        RunSettings("sobol", "hartmann6", indifference=0.1)
    assert info.value.field == "indifference"
    with pytest.raises(SettingError) as info:
        RunSettings("sobol", "hartmann6", tie_threshold=-1.0)
    assert info.value.field == "tie_threshold"


def test_bench_run_with_indifferent_oracle_is_deterministic() -> None:
    from localpbo_core.loop import run_session

    settings = RunSettings(
        "gipbor", "hartmann6", seed=2, budget=14, tie_threshold=0.5, indifference=0.05
    )
    a, b = run_session(Session(settings)), run_session(Session(settings))
    kinds = [x.kind for x in a.answers]
    assert AnswerKind.INDIFFERENT in kinds and AnswerKind.DECISIVE in kinds
    assert a.answers == b.answers and a.native == b.native
