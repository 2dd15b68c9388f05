"""The end-of-run recommendation (argmax posterior mean over all duels) vs the incumbent."""

from __future__ import annotations

import numpy as np
import torch
from optim_helpers import judged

from localpbo_core import make_optimizer
from localpbo_core.optimizers import Outcome
from localpbo_core.optimizers.recommendation import recommend
from localpbo_core.surrogate import PairwiseGPSurrogate


def _utility(theta: np.ndarray) -> float:
    return float(-np.sum((np.asarray(theta) - 0.6) ** 2))


def _run_with_a_late_upset(budget: int) -> tuple[object, dict[int, float]]:
    """Sobol on 2-D, noise-free duels on ``_utility`` except the last one, which a clearly
    worse candidate wins against the incumbent (an unlucky noisy duel)."""
    opt = make_optimizer("sobol", 2, seed=3, budget=budget)
    values: dict[int, float] = {}
    while not opt.done:
        ask = opt.ask()
        for c in ask.candidates:
            values[c.id] = _utility(c.theta)
        last = opt.evaluations_used >= budget
        outs = []
        for d in ask.duels:
            a, b = (
                (d.first, d.second) if values[d.first] >= values[d.second] else (d.second, d.first)
            )
            outs.append(Outcome(b, a) if last else Outcome(a, b))
        opt.tell(outs)
    return opt, values


def test_recommendation_outlives_a_lucky_win() -> None:
    opt, values = _run_with_a_late_upset(budget=30)
    best_id = max(values, key=values.__getitem__)
    assert opt.incumbent.id != best_id  # the upset crowned a worse candidate
    assert values[opt.incumbent.id] < values[best_id] - 0.05
    rec = recommend(opt)
    # the posterior weighs every duel: one upset does not undo the ones the upset's victim won
    assert rec.id != opt.incumbent.id
    assert values[rec.id] > values[opt.incumbent.id] + 0.05
    np.testing.assert_array_equal(rec.theta, opt.history.candidates[rec.id].theta)


def test_recommendation_is_the_posterior_mean_argmax() -> None:
    opt, _ = _run_with_a_late_upset(budget=24)
    X = torch.tensor(opt.train_inputs(), dtype=torch.float64)
    s = PairwiseGPSurrogate.fit(X, torch.tensor(opt.comparisons(), dtype=torch.long))
    mean = s.mean(X).detach().numpy()
    assert recommend(opt).id == int(np.argmax(mean))


def test_before_any_outcome_the_incumbent_is_returned() -> None:
    opt = make_optimizer("turpbo", 3, seed=0, budget=10)
    assert recommend(opt) is None
    opt.ask()
    assert recommend(opt) is opt.incumbent


def test_turpbo_recommendation_refits_from_its_last_surrogate() -> None:
    opt = make_optimizer("turpbo", 2, seed=1, budget=14)
    values: dict[int, float] = {}
    while not opt.done:
        ask = opt.ask()
        for c in ask.candidates:
            values[c.id] = _utility(c.theta)
        opt.tell(judged(values, ask.duels))
    assert opt.surrogate is not None
    X = torch.tensor(opt.train_inputs(), dtype=torch.float64)
    C = torch.tensor(opt.comparisons(), dtype=torch.long)
    s = PairwiseGPSurrogate.fit(X, C, warm_start=opt.surrogate)
    assert recommend(opt).id == int(np.argmax(s.mean(X).detach().numpy()))
