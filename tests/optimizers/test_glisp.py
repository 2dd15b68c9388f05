"""GLISp baseline: shared initial design, preferences seen by glis, budget, determinism,
improvement on a smooth problem, bad options."""

from __future__ import annotations

from unittest import mock

import numpy as np
import pytest
from optim_helpers import drive, utility

from localpbo_core.optimizers import Outcome, make_optimizer
from localpbo_core.optimizers.glisp import GLISpOptimizer, _glis_solvers

BUDGET = 22


@pytest.fixture(scope="module")
def run() -> GLISpOptimizer:
    opt = GLISpOptimizer(dim=2, seed=0, budget=BUDGET)
    drive(opt)
    return opt


def test_budget_accounting_and_king_of_the_hill(run):
    hist = run.history
    assert len(hist.candidates) == BUDGET
    assert len(hist.duels) == BUDGET - 1  # App. D.1: one comparison per new evaluation
    inc = hist.duels[0].second
    for duel, out in zip(hist.duels, hist.outcomes, strict=True):
        assert duel.second == inc  # each new point against the incumbent
        assert duel.first == max(duel.first, duel.second)
        inc = out.winner
    values = np.array([utility(c.theta) for c in hist.candidates])
    assert run.incumbent.id == int(np.argmax(values))  # noise-free: king = best evaluated


def test_glis_sees_exactly_the_outcomes(run):
    glis = run.glis
    # glis's preference list I holds [better, worse] pairs: the outcomes it was fed. The
    # last outcome is never fed (no acquisition after the final evaluation).
    fed = [[o.winner, o.loser] for o in run.history.outcomes[:-1]]
    assert [list(map(int, p)) for p in glis.I] == fed
    # glis's sample list starts with the same points the optimizer proposed
    X = np.array(glis.X[: BUDGET - 1])
    np.testing.assert_allclose(X, run.train_inputs()[: BUDGET - 1], atol=1e-12)


def test_shared_initial_design_and_warm_start():
    sobol = make_optimizer("sobol", dim=3, seed=5, budget=12, initial_design=4)
    glisp = make_optimizer("glisp", dim=3, seed=5, budget=12, initial_design=4)
    a, b = drive(sobol), drive(glisp)
    np.testing.assert_array_equal(np.stack(a[:4]), np.stack(b[:4]))
    assert glisp.n_initial_random == 10
    warm = np.array([0.1, 0.2, 0.9])
    opt = make_optimizer("glisp", dim=3, seed=5, budget=4, warm_start=warm)
    np.testing.assert_array_equal(drive(opt)[0], warm)
    big = GLISpOptimizer(dim=2, seed=1, budget=14, initial_design=12)
    assert big.n_initial_random == 12
    assert make_optimizer("glisp", dim=2, seed=0, batch_size=1).budget == 22


def test_deterministic_per_seed_and_restores_pso():
    solvers = _glis_solvers()
    original = solvers.pso
    runs = [np.stack(drive(GLISpOptimizer(dim=2, seed=s, budget=14))) for s in (2, 2, 3)]
    np.testing.assert_array_equal(runs[0], runs[1])
    assert not np.array_equal(runs[0], runs[2])
    assert solvers.pso is original


def test_improves_on_smooth_2d_problem(run):
    vals = np.array([utility(c.theta) for c in run.history.candidates])
    assert vals[10:].max() > vals[:10].max()  # better than its random phase
    assert utility(run.incumbent.theta) > -0.01  # optimum 0 at (0.3, 0.3)


def test_rejected_tell_mid_run_changes_nothing():
    clean = np.stack(drive(GLISpOptimizer(dim=2, seed=4, budget=14)))
    opt = GLISpOptimizer(dim=2, seed=4, budget=14)
    values: dict[int, float] = {}
    while not opt.done:
        ask = opt.ask()
        for c in ask.candidates:
            values[c.id] = utility(c.theta)
        d = ask.duels[0]
        right = Outcome(d.first, d.second) if values[d.first] >= values[d.second] else None
        right = right or Outcome(d.second, d.first)
        with pytest.raises(ValueError, match="unknown candidate"):
            opt.tell([Outcome(d.first, 99)])
        opt.tell([right])
    np.testing.assert_array_equal(opt.train_inputs(), clean)


def test_expected_max_evals_places_the_recalibrations():
    # glis's default E = 100: recalibrations at n + k (E - n) / 4, all in the first 100
    default = GLISpOptimizer(dim=2, seed=0, budget=400)
    np.testing.assert_array_equal(default.glis.RBFcalibrationSteps, [10, 32, 55, 78])
    assert default.glis.sepvalue == pytest.approx(1 / 100)
    # None: E is the run's budget (glis's solve()), recalibrations spread over the run
    spread = GLISpOptimizer(dim=2, seed=0, budget=400, expected_max_evals=None)
    np.testing.assert_array_equal(spread.glis.RBFcalibrationSteps, [10, 108, 205, 302])
    assert spread.glis.sepvalue == pytest.approx(1 / 400)
    # a design larger than E: only the recalibration at the end of the design is left
    warm = GLISpOptimizer(dim=2, seed=0, budget=400, initial_design=166)
    np.testing.assert_array_equal(warm.glis.RBFcalibrationSteps, [166])


def test_recalibrations_count_the_linear_programs():
    # A recalibration at N samples solves 10 (N - 1) LPs (leave each non-best sample out, for
    # 10 shape factors); an ordinary step one: counted through glis's own fit.
    counts = {}
    for label, e in (("default", 100), ("budget", None)):
        opt = GLISpOptimizer(dim=2, seed=3, budget=40, expected_max_evals=e)
        fit = opt.glis.get_rbf_weights
        with mock.patch.object(opt.glis, "get_rbf_weights", wraps=fit) as counted:
            drive(opt)
        counts[label] = counted.call_count
    steps = 40 - 10  # steps after the 10 random points that fit and solve an acquisition
    # E = 40 (budget): recalibrations at 10, 18, 25, 32 samples; E = 100: at 10 and 32 of
    # 10, 32, 55, 78 fall within 40 evaluations
    assert counts["budget"] == steps + sum(10 * (n - 1) for n in (10, 18, 25, 32))
    assert counts["default"] == steps + sum(10 * (n - 1) for n in (10, 32))


@pytest.mark.parametrize(
    ("options", "field"),
    [
        ({"n_initial_random": 1}, "n_initial_random"),
        ({"pso_iters": 0}, "pso_iters"),
        ({"pso_swarm_size": 2.5}, "pso_swarm_size"),
        ({"delta": -1.0}, "delta"),
        ({"batch_size": 2}, "batch_size"),
        ({"expected_max_evals": 0}, "expected_max_evals"),
        ({"expected_max_evals": 50.5}, "expected_max_evals"),
    ],
)
def test_bad_options_raise(options, field):
    with pytest.raises(ValueError, match=field):
        make_optimizer("glisp", dim=2, seed=0, **options)
