"""TuRPBO trust-region rules (paper App. C.5, Alg. TurPBO, TuRPBO table)."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch
from optim_helpers import drive

from localpbo_core import make_optimizer
from localpbo_core.optimizers import Outcome
from localpbo_core.optimizers.trust_region import (
    TREvent,
    TrustRegionState,
    perturbed_candidates,
    trust_region_bounds,
)


@pytest.mark.parametrize(
    ("d", "q", "fail"), [(2, 1, 4), (6, 1, 6), (33, 1, 33), (6, 4, 2), (33, 4, 9), (3, 8, 1)]
)
def test_tolerances_follow_the_table(d: int, q: int, fail: int) -> None:
    tr = TrustRegionState(dim=d, batch_size=q)
    assert tr.success_tolerance == d
    assert tr.failure_tolerance == fail
    assert (tr.length, tr.length_min, tr.length_max) == (0.8, 0.5**7, 1.6)


def test_expand_after_tau_succ_consecutive_successes_capped_at_lmax() -> None:
    tr = TrustRegionState(dim=3)
    assert [tr.update(True) for _ in range(3)] == [TREvent.NONE, TREvent.NONE, TREvent.EXPAND]
    assert tr.length == 1.6
    for _ in range(3):
        tr.update(True)
    assert tr.length == 1.6  # min(2L, L_max)
    # a failure in between resets the success counter
    tr = TrustRegionState(dim=3)
    for s in (True, True, False, True, True):
        assert tr.update(s) is not TREvent.EXPAND
    assert tr.length == 0.8 and tr.success_counter == 2 and tr.failure_counter == 0


def test_shrink_after_tau_fail_and_restart_below_lmin() -> None:
    tr = TrustRegionState(dim=2)  # tau_fail = 4
    lengths = []
    events = []
    for _ in range(4 * 7):
        events.append(tr.update(False))
        lengths.append(tr.length)
    shrinks = [i for i, e in enumerate(events) if e is TREvent.SHRINK]
    assert shrinks == [3, 7, 11, 15, 19, 23]
    assert lengths[23] == pytest.approx(0.8 / 2**6)
    # 0.8 / 2**7 = 0.00625 < 0.5**7 = 0.0078125: the 7th halving restarts the region
    assert events[27] is TREvent.RESTART
    assert tr.length == 0.8 and tr.restarts == 1
    assert tr.failure_counter == tr.success_counter == 0


def test_success_resets_failure_counter() -> None:
    tr = TrustRegionState(dim=2)
    for s in (False, False, False, True, False, False, False):
        assert tr.update(s) is TREvent.NONE
    assert tr.length == 0.8 and tr.failure_counter == 3


def test_bounds_are_lengthscale_weighted_with_unit_geometric_mean() -> None:
    center = np.full(3, 0.5)
    ls = np.array([0.1, 0.2, 0.4])
    lb, ub = trust_region_bounds(center, ls, 0.4)
    w = ls / (0.1 * 0.2 * 0.4) ** (1 / 3)
    np.testing.assert_allclose(ub - lb, w * 0.4)
    assert math.prod(ub - lb) == pytest.approx(0.4**3)  # volume L^d
    np.testing.assert_allclose((lb + ub) / 2, center)
    lb, ub = trust_region_bounds(np.array([0.0, 1.0, 0.5]), ls, 1.6)
    assert lb[0] == 0.0 and ub[1] == 1.0 and np.all(lb >= 0) and np.all(ub <= 1)


def test_perturbed_candidates_stay_in_box_and_mask_probability() -> None:
    d = 60
    rng = np.random.default_rng(0)
    center = rng.random(d)
    lb, ub = trust_region_bounds(center, np.full(d, 0.3), 0.5)
    x = perturbed_candidates(center, lb, ub, 1024, rng)
    assert x.shape == (1024, d)
    assert np.all(x >= lb) and np.all(x <= ub)
    changed = x != center
    assert changed.any(axis=1).all()
    # each coordinate perturbed with probability min(20/d, 1) = 1/3
    assert abs(changed.mean() - 20 / d) < 0.02


def _scripted(opt, wins):
    """Drive ``opt`` past its initial design, then answer candidate duels by ``wins``."""
    while opt.in_initial_design:
        ask = opt.ask()
        opt.tell([Outcome(d.first, d.second) for d in ask.duels])
    log = []
    for w in wins:
        center = opt.center.id
        ask = opt.ask()
        outs = []
        for d in ask.duels:
            new = {c.id for c in ask.candidates}
            cand_first = d.first in new
            if cand_first:
                outs.append(Outcome(d.first, d.second) if w else Outcome(d.second, d.first))
            else:  # challenge duel center vs global incumbent: the incumbent wins
                outs.append(Outcome(d.second, d.first))
        opt.tell(outs)
        log.append((ask, opt.tr.length, opt.events[-1] if opt.events else None, center))
    return log


def test_turpbo_state_machine_driven_by_scripted_outcomes(fake_fit: None) -> None:
    d = 2
    opt = make_optimizer("turpbo", d, seed=0, budget=200)
    log = _scripted(opt, [True, True] + [False] * 32)
    assert log[1][1] == 1.6 and log[1][2] is TREvent.EXPAND
    assert log[5][1] == 0.8 and log[5][2] is TREvent.SHRINK
    # every iteration duels its candidate against the center/incumbent
    inc_before = opt.incumbent.id
    assert all(a.duels[0].second == c for a, _, _, c in log)
    # two successes moved the center (= incumbent) to the second winner
    assert log[2][3] == log[1][0].candidates[0].id == inc_before
    # from 1.6, seven halvings reach 0.0125; the eighth (0.00625 < 0.5**7) restarts
    events = [e for _, _, e, _ in log]
    assert events.count(TREvent.SHRINK) == 7 and events[-1] is TREvent.RESTART
    # the restart proposal is one fresh point dueled against the global incumbent
    ask = opt.ask()
    assert len(ask.candidates) == 1 and ask.duels[0].second == inc_before
    opt.tell([Outcome(inc_before, ask.candidates[0].id)])  # incumbent keeps the crown
    assert opt.incumbent.id == inc_before and opt.center.id == ask.candidates[0].id
    # next iteration: candidate vs new center; the center already lost against the king,
    # so no challenge duel yet
    ask = opt.ask()
    assert [(x.first, x.second) for x in ask.duels] == [(ask.candidates[0].id, opt.center.id)]
    cid = ask.candidates[0].id
    opt.tell([Outcome(cid, opt.center.id)])
    assert opt.center.id == cid and opt.incumbent.id == inc_before
    # the new center is challenged once against the global incumbent
    ask = opt.ask()
    assert (cid, inc_before) in [(x.first, x.second) for x in ask.duels]
    new = ask.candidates[0].id
    opt.tell([Outcome(cid, inc_before), Outcome(new, cid)])
    # the center beat the king, then the candidate beat the center: it is the new king
    assert opt.incumbent.id == new and opt.center.id == new


def test_turpbo_batch_duels_and_success_rule(fake_fit: None) -> None:
    opt = make_optimizer("turpbo", 3, seed=1, budget=40, batch_size=3)
    while opt.in_initial_design:
        ask = opt.ask()
        opt.tell([Outcome(x.first, x.second) for x in ask.duels])
    inc = opt.incumbent.id
    ask = opt.ask()
    assert len(ask.candidates) == 3
    assert all(x.second == inc for x in ask.duels)
    ids = [c.id for c in ask.candidates]
    # two winners: the first in proposal order becomes the incumbent, counted as a success
    opt.tell([Outcome(inc, ids[0]), Outcome(ids[1], inc), Outcome(ids[2], inc)])
    assert opt.incumbent.id == ids[1] and opt.tr.success_counter == 1
    for c in ask.candidates:
        lb, ub = trust_region_bounds(opt.history.candidates[inc].theta, np.full(3, 0.2), 0.8)
        assert np.all(c.theta >= lb - 1e-12) and np.all(c.theta <= ub + 1e-12)


def test_turpbo_finds_a_better_point_with_the_real_surrogate() -> None:
    opt = make_optimizer("turpbo", 2, seed=3, budget=14)
    thetas = drive(opt)
    vals = [-np.sum((t - 0.3) ** 2) for t in thetas]
    assert max(vals[2:]) > max(vals[:2])
    assert opt.surrogate is not None


@pytest.mark.parametrize(
    ("acq", "q"),
    [
        ("ts", 1),
        ("ts", 2),
        ("ts_discrete", 1),
        ("ts_discrete", 2),
        ("qeubo", 1),
        ("qeubo", 2),
        ("ei", 1),
    ],
)
def test_turpbo_real_surrogate_is_deterministic_and_stays_in_region(acq: str, q: int) -> None:
    runs = []
    for _ in range(2):
        opt = make_optimizer("turpbo", 3, seed=8, budget=4 + 2 * q, acquisition=acq, batch_size=q)
        while not opt.done:
            center = opt.center.theta if opt.center is not None else None
            length = opt.tr.length  # the tell below may shrink the region
            ask = opt.ask()
            opt.tell([Outcome(d.second, d.first) for d in ask.duels])  # incumbents keep winning
            if opt.surrogate is not None and center is not None:
                ls = opt.surrogate.lengthscale.numpy()
                lb, ub = trust_region_bounds(center, ls, length)
                for c in ask.candidates:
                    assert np.all(c.theta >= lb - 1e-12) and np.all(c.theta <= ub + 1e-12)
        runs.append(np.stack([c.theta for c in opt.history.candidates]))
    np.testing.assert_array_equal(runs[0], runs[1])


def test_hyperparameter_refit_every_k_holds_them_in_between(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    from localpbo_core.surrogate import PairwiseGPSurrogate

    original = PairwiseGPSurrogate.fit.__func__
    fixed: list[bool] = []

    def spy(cls, X, comparisons, lengthscale=None, outputscale=None, warm_start=None, **kw):
        fixed.append(lengthscale is not None and outputscale is not None)
        if lengthscale is not None:
            assert torch.equal(lengthscale, warm_start.lengthscale)
            assert outputscale == warm_start.outputscale
        return original(cls, X, comparisons, lengthscale, outputscale, warm_start, **kw)

    monkeypatch.setattr(PairwiseGPSurrogate, "fit", classmethod(spy))
    opt = make_optimizer("turpbo", 2, seed=4, budget=9, hyperparameter_refit_every=3)
    drive(opt)
    assert fixed == [False, True, True, False, True, True, False]
    fixed.clear()
    drive(make_optimizer("turpbo", 2, seed=4, budget=5))
    assert fixed == [False, False, False]
    with pytest.raises(ValueError, match="hyperparameter_refit_every"):
        make_optimizer("turpbo", 2, hyperparameter_refit_every=0)


def test_expected_improvement_matches_quadrature() -> None:
    # brute force: E[max(f - best, 0)] for f ~ N(m, s^2) by adaptive quadrature
    import scipy.integrate
    import scipy.stats

    from localpbo_core.optimizers.acquisition import expected_improvement

    for m, s, best in ((0.3, 0.5, 0.1), (-1.0, 0.2, 0.0), (2.0, 1.5, 2.5), (0.0, 1e-3, 0.0)):
        dens = scipy.stats.norm(m, s).pdf
        lo, hi = max(best, m - 12 * s), max(best, m + 12 * s)
        ref = scipy.integrate.quad(lambda t, d=dens, b=best: (t - b) * d(t), lo, hi)[0]
        ana = float(expected_improvement(torch.tensor(m), torch.tensor(s * s), best))
        assert ana == pytest.approx(ref, abs=1e-7)


def _ei_run() -> tuple[object, np.ndarray]:
    opt = make_optimizer("turpbo", 2, seed=5, budget=10, acquisition="ei")
    drive(opt)
    return opt, np.stack([c.theta for c in opt.history.candidates])


def test_ei_gradient_matches_finite_differences_and_argmax_beats_a_grid() -> None:
    from localpbo_core.optimizers.acquisition import ei_batch, expected_improvement

    opt, _ = _ei_run()
    sur = opt.surrogate
    inc = torch.tensor(opt.incumbent.theta, dtype=torch.float64)
    best = float(sur.mean(inc).detach())

    def ei(x: torch.Tensor) -> torch.Tensor:
        m, c = sur.posterior_mean_cov(x)
        return expected_improvement(m, torch.diagonal(c), best)

    rng = np.random.default_rng(0)
    for x0 in rng.random((4, 2)):
        x = torch.tensor(x0[None], dtype=torch.float64, requires_grad=True)
        (g,) = torch.autograd.grad(ei(x).sum(), x)
        fd = np.zeros(2)
        for i in range(2):
            e = np.zeros(2)
            e[i] = 1e-6
            with torch.no_grad():
                hi = float(ei(torch.tensor((x0 + e)[None])))
                lo = float(ei(torch.tensor((x0 - e)[None])))
            fd[i] = (hi - lo) / 2e-6
        np.testing.assert_allclose(g.numpy()[0], fd, rtol=1e-4, atol=1e-8)
    # the maximiser in a box is at least as good as every point of a fine grid (brute force)
    lb, ub = np.array([0.2, 0.1]), np.array([0.7, 0.5])
    raw = lb + (ub - lb) * rng.random((64, 2))
    xs = ei_batch(
        lambda x: (sur.posterior_mean_cov(x)[0], torch.diagonal(sur.posterior_mean_cov(x)[1])),
        best,
        raw,
        lb,
        ub,
    )
    assert xs.shape == (1, 2) and np.all(xs >= lb) and np.all(xs <= ub)
    g1, g2 = np.meshgrid(np.linspace(lb[0], ub[0], 41), np.linspace(lb[1], ub[1], 41))
    grid = np.column_stack([g1.ravel(), g2.ravel()])
    with torch.no_grad():
        grid_vals = np.concatenate([ei(torch.tensor(c)).numpy() for c in np.split(grid, 41)])
        chosen = float(ei(torch.tensor(xs)))
    assert chosen >= grid_vals.max() - 1e-6 * max(1.0, abs(grid_vals.max()))


def test_ei_improves_and_is_deterministic_and_refuses_batches() -> None:
    _, a = _ei_run()
    _, b = _ei_run()
    np.testing.assert_array_equal(a, b)
    vals = [-np.sum((t - 0.3) ** 2) for t in a]
    assert max(vals[2:]) > max(vals[:2])
    with pytest.raises(ValueError, match="batch_size"):
        make_optimizer("turpbo", 2, seed=0, budget=10, acquisition="ei", batch_size=2)
