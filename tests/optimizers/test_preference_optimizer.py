"""Ask/tell bookkeeping shared by every optimizer (paper App. D.1)."""

from __future__ import annotations

import numpy as np
import pytest
from optim_helpers import drive, utility

from localpbo_core import make_optimizer
from localpbo_core.optimizers import (
    BudgetExhausted,
    Duel,
    InvalidOutcome,
    Outcome,
    PendingDuels,
    available_optimizers,
)


def _state(opt):
    h = opt.history
    return (
        [(c.id, c.theta.tobytes()) for c in h.candidates],
        h.duels,
        h.outcomes,
        opt.pending_duels,
        None if opt.incumbent is None else opt.incumbent.id,
        opt.evaluations_used,
    )


def test_ids_budget_and_comparisons_count() -> None:
    d = 3
    opt = make_optimizer("sobol", d, seed=4, budget=2 + 10 * d)
    thetas = drive(opt)
    h = opt.history
    assert [c.id for c in h.candidates] == list(range(2 + 10 * d))
    assert len(thetas) == opt.budget == opt.evaluations_used
    # App. D.1: N evaluations with king-of-the-hill duels give N - 1 comparisons.
    assert len(h.outcomes) == len(h.duels) == 1 + 10 * d
    with pytest.raises(BudgetExhausted):
        opt.ask()


def test_incumbent_is_the_best_seen_under_noise_free_duels() -> None:
    opt = make_optimizer("sobol", 4, seed=7, budget=30, initial_design=5)
    thetas = drive(opt)
    best = int(np.argmax([utility(t) for t in thetas]))
    assert opt.incumbent.id == best


def test_initial_design_is_shared_and_sequentially_dueled(fake_fit: None) -> None:
    a = make_optimizer("sobol", 5, seed=11, budget=12, initial_design=4)
    b = make_optimizer("turpbo", 5, seed=11, budget=12, initial_design=4)
    drive(a)
    drive(b)
    ta = [c.theta for c in a.history.candidates[:4]]
    tb = [c.theta for c in b.history.candidates[:4]]
    np.testing.assert_array_equal(np.stack(ta), np.stack(tb))
    # different seed -> different design
    c = make_optimizer("sobol", 5, seed=12, budget=4, initial_design=4)
    drive(c)
    assert not np.array_equal(c.history.candidates[0].theta, ta[0])
    # sequential duels: candidate i+1 against the current winner
    duels = a.history.duels[:3]
    assert duels[0] == Duel(1, 0)
    assert [d.first for d in duels] == [1, 2, 3]


def test_warm_start_replaces_first_design_point() -> None:
    theta0 = np.linspace(0.1, 0.9, 6)
    opt = make_optimizer("sobol", 6, seed=0, budget=8, warm_start=theta0)
    ask = opt.ask()
    np.testing.assert_array_equal(ask.candidates[0].theta, theta0)
    plain = make_optimizer("sobol", 6, seed=0, budget=8)
    np.testing.assert_array_equal(plain.ask().candidates[1].theta, ask.candidates[1].theta)


@pytest.mark.parametrize(
    ("kwargs", "needle"),
    [
        ({"warm_start": [0.5] * 5}, "warm_start"),
        ({"warm_start": [0.5, 0.5, float("nan"), 0.5, 0.5, 0.5]}, "warm_start"),
        ({"warm_start": [0.5, 0.5, 1.5, 0.5, 0.5, 0.5]}, "warm_start"),
        ({"budget": 3, "initial_design": 4}, "budget"),
        ({"initial_design": 1}, "initial_design"),
        ({"batch_size": 0}, "batch_size"),
        ({"colour": "red"}, "colour"),
        ({"seed": -1}, "seed"),
    ],
)
def test_bad_options_name_the_option(kwargs: dict, needle: str) -> None:
    args = {"seed": 0, "budget": 20}
    args.update(kwargs)
    for name in available_optimizers():
        with pytest.raises(ValueError, match=needle):
            make_optimizer(name, 6, **args)


def test_unknown_algorithm_and_bad_dim() -> None:
    with pytest.raises(ValueError, match="algorithm"):
        make_optimizer("nope", 3)
    with pytest.raises(ValueError, match="dim"):
        make_optimizer("sobol", 0)
    with pytest.raises(ValueError, match="acquisition"):
        make_optimizer("turpbo", 3, acquisition="nope")


def test_default_budget_is_2_plus_10d() -> None:
    assert make_optimizer("turpbo", 6).budget == 62
    assert make_optimizer("sobol", 33, initial_design=165).budget == 165 + 330


def test_pending_duels_block_ask_and_partial_tells() -> None:
    opt = make_optimizer("sobol", 2, seed=1, budget=10, batch_size=3)
    ask = opt.ask()
    opt.tell([Outcome(0, 1)])
    ask = opt.ask()
    assert len(ask.candidates) == 3 and len(ask.duels) == 3
    with pytest.raises(PendingDuels):
        opt.ask()
    d0, d1, d2 = ask.duels
    opt.tell([Outcome(d0.second, d0.first)])
    assert opt.pending_duels == (d1, d2)
    opt.tell([])
    opt.tell([Outcome(d2.first, d2.second), Outcome(d1.first, d1.second)])
    assert opt.pending_duels == ()
    # two winners against the incumbent: the first in proposal order (lowest id) wins
    assert opt.incumbent.id == d1.first


def test_rejected_tell_leaves_state_unchanged() -> None:
    opt = make_optimizer("sobol", 2, seed=3, budget=10)
    opt.tell([Outcome(1, 0)] if opt.ask() else [])
    ask = opt.ask()
    (duel,) = ask.duels
    before = _state(opt)
    bad = [
        [Outcome(duel.first, 99)],  # unknown id
        [Outcome(duel.first, 0)],  # a duel that was not asked
        [Outcome(1, 0)],  # repeated outcome of an earlier duel
        [Outcome(duel.first, duel.second), Outcome(duel.second, duel.first)],  # twice now
        [Outcome(duel.first, duel.first)],  # self-duel
        [Outcome(duel.first, duel.second), "winner"],  # not an Outcome
        [Outcome(duel.first, -1)],
    ]
    for outs in bad:
        with pytest.raises(InvalidOutcome):
            opt.tell(outs)
        assert _state(opt) == before
    opt.tell([Outcome(duel.first, duel.second)])
    with pytest.raises(InvalidOutcome, match="repeated"):
        opt.tell([Outcome(duel.first, duel.second)])


def test_invalid_outcome_is_a_value_error() -> None:
    assert issubclass(InvalidOutcome, ValueError)


@pytest.mark.parametrize("name", ["sobol", "turpbo"])
def test_determinism_same_seed_same_candidates(name: str, fake_fit: None) -> None:
    runs = []
    for _ in range(2):
        opt = make_optimizer(name, 4, seed=5, budget=14)
        runs.append(np.stack(drive(opt)))
    np.testing.assert_array_equal(runs[0], runs[1])
    other = np.stack(drive(make_optimizer(name, 4, seed=6, budget=14)))
    assert not np.array_equal(runs[0], other)


def test_failed_ask_leaves_state_unchanged(monkeypatch: pytest.MonkeyPatch) -> None:
    from localpbo_core.optimizers.turpbo import TuRPBO

    opt = make_optimizer("turpbo", 2, seed=0, budget=6)
    ask = opt.ask()
    opt.tell([Outcome(d.first, d.second) for d in ask.duels])
    before = _state(opt)

    def boom(self, q, rng):
        self._register([np.full(2, 0.5)])
        raise RuntimeError("surrogate failed")

    monkeypatch.setattr(TuRPBO, "_select", boom)
    with pytest.raises(RuntimeError, match="surrogate failed"):
        opt.ask()
    assert _state(opt) == before


def test_options_handed_on_as_typed_keywords_are_listed_with_their_base_defaults() -> None:
    """``**options: Unpack[SomeOptions]`` stands for the keys of the TypedDict, each with the
    default of the nearest base class that names it."""
    from localpbo_core.optimizers.registry import optimizer_defaults, optimizer_options

    assert optimizer_options("sobol") == [
        "initial_design",
        "warm_start",
        "tie_threshold",
        "batch_size",
    ]
    hybrid = optimizer_defaults("hybrid")
    assert hybrid["num_mc_samples"] == 512 and hybrid["confidence"] == 1.0
    assert hybrid["initial_design"] == 2 and hybrid["warm_start"] is None
    gipbor = optimizer_defaults("gipbor")
    assert gipbor["step_size"] == 0.5 and gipbor["hyperparameters"] is None
    assert "radii" not in optimizer_options("gipbor") and "radii" in optimizer_options("gipbo")
