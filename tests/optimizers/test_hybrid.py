"""The hybrid (TuRPBO exploration + kernel-metric local steps): its global mode is TuRPBO's,
the handover and hand-back rules, the local step, determinism, speculation (deep copies),
validated tells and "can't tell" answers."""

from __future__ import annotations

import copy
import re
from collections.abc import Iterator

import numpy as np
import pytest
import torch
from optim_helpers import drive, judged, utility

from localpbo_core.optimizers import (
    Ask,
    Candidate,
    Indifferent,
    InvalidOutcome,
    Outcome,
    PreferenceOptimizer,
    make_optimizer,
)
from localpbo_core.optimizers.hybrid import Hybrid, slope_confidence
from localpbo_core.optimizers.prefsqp import negative_definite_modification
from localpbo_core.surrogate import Surrogate


def _drive_by_theta(opt: PreferenceOptimizer) -> list[np.ndarray]:
    """Like ``drive``, judging every candidate (also those asked before) by its theta."""
    while not opt.done:
        ask = opt.ask()
        cands = opt.history.candidates
        opt.tell(
            [
                Outcome(d.first, d.second)
                if utility(cands[d.first].theta) >= utility(cands[d.second].theta)
                else Outcome(d.second, d.first)
                for d in ask.duels
            ]
        )
    return [c.theta for c in opt.history.candidates]


def _mode_asks(
    opt: Hybrid, mode: str = "local"
) -> Iterator[tuple[Ask, Candidate, Surrogate, torch.Tensor]]:
    """Drive ``opt`` noise-free on ``utility``; yield every ask of ``mode`` (a local step or a
    probe), before it is answered, with the center, the surrogate and the phase's origin (the
    center without probes) as a tensor (duels the caller answers are not answered again)."""
    values: dict[int, float] = {}
    while not opt.done:
        before = len(opt.modes)
        ask = opt.ask()
        for c in ask.candidates:
            values[c.id] = utility(c.theta)
        if len(opt.modes) > before and opt.modes[-1] == mode:
            center, sur = opt.center, opt.surrogate
            assert center is not None and sur is not None
            origin = center.theta if opt.origin is None else opt.origin
            yield ask, center, sur, torch.tensor(origin, dtype=torch.float64)
        if opt.pending_duels == tuple(ask.duels):
            opt.tell(judged(values, ask.duels))


def _older_wins(opt: PreferenceOptimizer) -> None:
    """Every newer candidate loses its duel."""
    while not opt.done:
        ask = opt.ask()
        opt.tell([Outcome(min(d.first, d.second), max(d.first, d.second)) for d in ask.duels])


def test_slope_confidence() -> None:
    g = np.array([1.0, 0.0])
    sigma = np.diag([0.25, 4.0])
    assert slope_confidence(g, g, sigma) == pytest.approx(2.0)  # 1 / sqrt(0.25)
    assert slope_confidence(g, np.array([0.0, 1.0]), sigma) == 0.0  # no ascent along u
    assert slope_confidence(g, -g, sigma) == 0.0
    assert slope_confidence(g, g, np.zeros((2, 2))) == float("inf")
    assert slope_confidence(g, np.zeros(2), sigma) == 0.0


def test_without_handover_it_is_turpbo() -> None:
    hybrid = make_optimizer("hybrid", 3, seed=5, budget=24, confidence=1e300)
    turpbo = make_optimizer("turpbo", 3, seed=5, budget=24)
    a, b = drive(hybrid), drive(turpbo)
    assert all(np.array_equal(x, y) for x, y in zip(a, b, strict=True))
    assert set(hybrid.modes) == {"global"}


def test_until_the_first_handover_it_asks_turpbos_candidates() -> None:
    hybrid = make_optimizer("hybrid", 4, seed=2, budget=42, confidence=0.5)
    a = drive(hybrid)
    first_local = hybrid.modes.index("local")  # the threshold is reached on this seed
    assert first_local > 5
    turpbo = make_optimizer("turpbo", 4, seed=2, budget=42)
    b = drive(turpbo)
    n = 2 + first_local  # the initial pair, then one candidate per ask (q = 1)
    assert all(np.array_equal(x, y) for x, y in zip(a[:n], b[:n], strict=True))
    assert not np.array_equal(a[n], b[n])


@pytest.mark.parametrize("probes_per_dim", [0.0, 1.0])
def test_local_step_is_the_kernel_metric_gradient_step(probes_per_dim: float) -> None:
    """The step from the fit of its own ask, which has seen the phase's probes."""
    opt = make_optimizer(
        "hybrid",
        3,
        seed=1,
        budget=32 + 12 * int(probes_per_dim),
        confidence=0.0,
        stall_duels=100,
        probes_per_dim=probes_per_dim,
    )
    assert isinstance(opt, Hybrid)
    checked = moved = 0
    for ask, center, sur, x in _mode_asks(opt):
        assert len(ask.candidates) == 1
        g = sur.mean_gradient(x).detach().numpy()
        ls = sur.lengthscale.detach().numpy()
        eta = 0.5 * 0.5**opt._losses
        expected = np.clip(x.numpy() + eta * g / np.sqrt(np.sum(g**2 / ls**2)), 0, 1)
        np.testing.assert_allclose(ask.candidates[0].theta, expected, atol=1e-12)
        assert (ask.duels[0].first, ask.duels[0].second) == (ask.candidates[0].id, center.id)
        checked += 1
        moved += not np.array_equal(x.numpy(), center.theta)
    assert checked >= 10
    assert (moved > 0) == (probes_per_dim > 0)  # a probe won: the step still starts at x_o


def test_newton_direction_option() -> None:
    opt = make_optimizer(
        "hybrid", 3, seed=1, budget=24, confidence=0.0, local_direction="newton", stall_duels=100
    )
    assert isinstance(opt, Hybrid)
    checked = 0
    for ask, center, sur, x in _mode_asks(opt):
        g = sur.mean_gradient(x).detach().numpy()
        H = sur.mean_hessian(x).detach().numpy()
        u = -np.linalg.solve(negative_definite_modification(H), g)
        step = ask.candidates[0].theta - center.theta
        inside = np.all((ask.candidates[0].theta > 0) & (ask.candidates[0].theta < 1))
        if inside:  # not projected: parallel to the Newton direction
            cos = step @ u / (np.linalg.norm(step) * np.linalg.norm(u))
            assert cos == pytest.approx(1.0, abs=1e-9)
            checked += 1
    assert checked >= 3


@pytest.mark.parametrize(("stall", "cooldown"), [(3, 2), (2, 4)])
def test_hand_back_after_stall_duels_losses_then_cooldown(stall: int, cooldown: int) -> None:
    # confidence 0: every check hands over; every new candidate loses. d = 2: tau_fail = 4,
    # the region shrinks every 4 failures and restarts after 28 (budget 26: no restart)
    opt = make_optimizer(
        "hybrid", 2, seed=0, budget=26, confidence=0.0, stall_duels=stall, cooldown=cooldown
    )
    assert isinstance(opt, Hybrid)
    _older_wins(opt)
    assert opt.tr.restarts == 0
    pattern = (["local"] * stall + ["global"] * cooldown) * 10
    assert opt.modes == pattern[: len(opt.modes)]
    assert len(opt.modes) == 24


def test_a_win_resets_the_step_and_keeps_local_mode() -> None:
    opt = make_optimizer("hybrid", 2, seed=0, budget=40, confidence=0.0, stall_duels=3)
    assert isinstance(opt, Hybrid)
    drive(opt)  # noise-free on a smooth problem: local steps win
    runs = "".join("L" if m == "local" else "g" for m in opt.modes)
    assert "LLLL" in runs  # more than stall_duels local steps in a row: wins reset the count


def test_determinism_and_seed_dependence() -> None:
    runs = [drive(make_optimizer("hybrid", 3, seed=s, budget=30)) for s in (4, 4, 5)]
    assert all(np.array_equal(a, b) for a, b in zip(runs[0], runs[1], strict=True))
    assert not all(np.array_equal(a, b) for a, b in zip(runs[0], runs[2], strict=True))


def test_improves_on_smooth_problem_under_noise() -> None:
    rng = np.random.default_rng(0)
    gaps, used_local = [], 0
    for seed in range(3):
        opt = make_optimizer("hybrid", 6, seed=seed, budget=62)
        # noise of 10 % of the range of the utility on the cube
        vals = np.array([utility(t) for t in drive(opt, noise=0.1 * 2.94, rng=rng)])
        gaps.append(1.0 - vals.max() / vals[:2].max())
        used_local += "local" in opt.modes
    assert np.mean(gaps) >= 0.5, gaps
    assert used_local >= 1


@pytest.mark.parametrize("probes_per_dim", [0.0, 1.0])
def test_deep_copy_mid_local_phase_continues_identically(probes_per_dim: float) -> None:
    """A copy taken mid local phase (with probes: mid probes) continues as the original."""
    opt = make_optimizer(
        "hybrid",
        3,
        seed=3,
        budget=30 + 10 * int(probes_per_dim),
        confidence=0.0,
        probes_per_dim=probes_per_dim,
    )
    assert isinstance(opt, Hybrid)

    def mid_phase() -> bool:
        if probes_per_dim:
            return opt._probes_left == 2
        return opt.mode == "local"

    values: dict[int, float] = {}
    while not (mid_phase() and opt.evaluations_used > 8):
        ask = opt.ask()
        for c in ask.candidates:
            values[c.id] = utility(c.theta)
        opt.tell(judged(values, ask.duels))
    twin = copy.deepcopy(opt)
    a, b = _drive_by_theta(opt), _drive_by_theta(twin)
    assert all(np.array_equal(x, y) for x, y in zip(a, b, strict=True))
    assert ("probe" in opt.modes) == bool(probes_per_dim)


def test_a_refused_tell_leaves_a_local_step_untouched() -> None:
    def run(bad: bool) -> list[np.ndarray]:
        opt = make_optimizer("hybrid", 3, seed=3, budget=24, confidence=0.0)
        values: dict[int, float] = {}
        while not opt.done:
            ask = opt.ask()
            for c in ask.candidates:
                values[c.id] = utility(c.theta)
            if bad:
                for wrong in (Outcome(0, 0), Outcome(ask.duels[0].first, 10_000), "x"):
                    with pytest.raises(InvalidOutcome):
                        opt.tell([wrong])  # type: ignore[list-item]
            opt.tell(judged(values, ask.duels))
        return [c.theta for c in opt.history.candidates]

    a, b = run(False), run(True)
    assert all(np.array_equal(x, y) for x, y in zip(a, b, strict=True))


def test_cant_tell_answers_are_no_win_and_are_modelled() -> None:
    with pytest.raises(InvalidOutcome):
        make_optimizer("hybrid", 2, seed=0, budget=20).tell([Indifferent(0, 1)])
    opt = make_optimizer(
        "hybrid", 2, seed=0, budget=30, confidence=0.0, stall_duels=2, tie_threshold=0.5
    )
    assert isinstance(opt, Hybrid)
    local_ties = 0
    for ask, center, _, _ in _mode_asks(opt):
        # a local step answered "can't tell": no win, the center stays
        opt.tell([Indifferent(d.first, d.second) for d in ask.duels])
        assert opt.center == center
        local_ties += 1
    # two "can't tell" local steps in a row hand back: local runs are at most 2 long
    runs = "".join("L" if m == "local" else "g" for m in opt.modes)
    assert local_ties >= 4 and "LLL" not in runs and "LL" in runs
    assert len(opt.ties()) == local_ties


def test_validation_names_the_field() -> None:
    for kw, field in (
        ({"confidence": -1.0}, "confidence"),
        ({"local_direction": "steepest"}, "local_direction"),
        ({"step_size": 0.0}, "step_size"),
        ({"stall_duels": 0}, "stall_duels"),
        ({"cooldown": -1}, "cooldown"),
        ({"probes_per_dim": -0.5}, "probes_per_dim"),
        ({"probe_metric": "chebyshev"}, "probe_metric"),
        ({"probe_scale": 0.0}, "probe_scale"),
        ({"acquisition": "ucb"}, "acquisition"),
    ):
        with pytest.raises(ValueError, match=field):
            make_optimizer("hybrid", 3, **kw)


@pytest.mark.parametrize("probes_per_dim", [0.0, 0.5])
def test_resume_replays_recorded_answers_into_the_same_run(probes_per_dim: float) -> None:
    """A resumed run (``localpbo run --resume``) rebuilds the session and re-feeds the recorded
    answers in order; the hybrid then asks the same candidates, local steps (and probes)
    included."""
    from localpbo_core.session import Answer, Session
    from localpbo_core.settings import RunSettings

    settings = RunSettings(
        algorithm="hybrid",
        problem="hartmann6",
        seed=2,
        budget=30,
        tie_threshold=0.5,
        indifference=0.05,
        optimizer_options={"confidence": 0.0, "probes_per_dim": probes_per_dim},
    )

    def live(session: Session, answers: list[Answer], stop: int | None = None) -> list[bytes]:
        oracle = session.oracle()
        values = {c.id: session.evaluate(c) for c in session.optimizer.history.candidates}
        thetas = []
        while not session.done and (stop is None or len(answers) < stop):
            step = session.ask()
            for cand in step.candidates:
                values[cand.id] = session.evaluate(cand)
                thetas.append(cand.theta.tobytes())
            for duel in step.duels:
                first = oracle.judge(duel.duel_id, values[duel.first], values[duel.second])
                answer = (
                    Answer.indifferent(duel)
                    if first is None
                    else Answer.decisive(duel, duel.first if first else duel.second)
                )
                assert session.offer(answer).accepted
                answers.append(answer)
        return thetas

    recorded: list[Answer] = []
    original = Session(settings)
    full = live(original, recorded)
    modes = original.optimizer.modes  # type: ignore[attr-defined]
    assert "local" in modes and ("probe" in modes) == (probes_per_dim > 0)
    # resume: replay the first answers (every ask they answer), then continue live
    resumed = Session(settings)
    replayed: list[bytes] = []
    it = iter(recorded[:17])
    for answer in it:
        step = resumed.ask()
        replayed += [c.theta.tobytes() for c in step.candidates]
        assert resumed.offer(answer).accepted
        for _ in range(len(step.duels) - 1):
            assert resumed.offer(next(it)).accepted
    rest = live(resumed, list(recorded[:17]))
    assert replayed + rest == full


@pytest.mark.parametrize(
    ("metric", "scale"), [("kernel", 1.0), ("euclidean", 1.0), ("kernel", 0.5), ("euclidean", 0.5)]
)
def test_probes_are_gipbors_queries_dueled_against_the_center(metric: str, scale: float) -> None:
    """A probe: one candidate at distance in [0.05, 0.2] from the phase's origin (GIPBOr's
    region; ``kernel``: at distance in [0.5, 2] in the metric of the lengthscales of the fit
    that started the phase), both times ``probe_scale``, before projection onto the cube,
    dueled against the center, and no refit. The origin is the center at the phase's start; a
    winning probe moves the center only."""
    opt = make_optimizer(
        "hybrid",
        5,
        seed=4,
        budget=80,
        confidence=0.0,
        probes_per_dim=1.0,
        probe_metric=metric,
        probe_scale=scale,
    )
    assert isinstance(opt, Hybrid) and opt.probes == 5
    fits: dict[int, object] = {}  # mode index of a probe -> the model after its ask
    checked = 0
    away = 0
    radii: list[float] = []
    for ask, center, _, x in _mode_asks(opt, "probe"):
        fits[len(opt.modes) - 1] = opt._refitter.surrogate
        assert len(ask.candidates) == 1 and opt.origin is not None
        theta, origin = ask.candidates[0].theta, x.numpy()
        assert (ask.duels[0].first, ask.duels[0].second) == (ask.candidates[0].id, center.id)
        if np.all((theta > 0) & (theta < 1)):
            if metric == "euclidean":
                radii.append(float(np.linalg.norm(theta - origin)) / 0.1)
            else:
                radii.append(float(np.linalg.norm((theta - origin) / opt._origin_scale)))
        checked += 1
        away += not np.array_equal(origin, center.theta)
    assert checked >= 15 and away > 0
    # radii in [0.5 s, 2 s] (euclidean: in units of 0.1), spread over most of it
    assert len(radii) >= 5
    assert 0.5 * scale - 1e-12 <= min(radii) < 0.9 * scale < 1.6 * scale < max(radii)
    assert max(radii) <= 2.0 * scale + 1e-12
    # consecutive probes of a phase share the fit of the ask before them: no refit
    following = [i for i in fits if i - 1 in fits]
    assert len(following) >= 10
    assert all(fits[i] is fits[i - 1] for i in following)


def test_a_phase_is_probes_then_steps() -> None:
    """Handover: ``ceil(probes_per_dim d)`` probes, then steps; a winning step starts a new
    phase of probes, a losing one halves the next step without probes, ``stall_duels`` losing
    steps hand back; a restart of the region (the fresh point, "R") or the budget's end cuts a
    phase short."""
    opt = make_optimizer(
        "hybrid", 4, seed=1, budget=60, confidence=0.0, probes_per_dim=0.75, stall_duels=3
    )
    assert isinstance(opt, Hybrid) and opt.probes == 3
    trace = ""  # per ask after the initial design: p/l/g, upper case if its candidate won
    values: dict[int, float] = {}
    while not opt.done:
        before, restart = len(opt.modes), opt._restart_pending
        ask = opt.ask()
        for c in ask.candidates:
            values[c.id] = utility(c.theta)
        outcomes = judged(values, ask.duels)
        opt.tell(outcomes)
        if restart:
            trace += "R"
        elif len(opt.modes) > before:
            mode = opt.modes[-1][0]
            trace += mode.upper() if outcomes[0].winner == ask.candidates[0].id else mode
    # seed 1 exercises every rule: wins and losses of probes and steps, a hand-back after
    # three losing steps, the cooldown's four region iterations, a restart
    assert trace[:3] in ("ppp", "ppP", "pPp", "pPP", "Ppp", "PpP", "PPp", "PPP")
    assert re.search("lll[gG]{4}[pP]", trace) and "R" in trace
    # three losing steps hand back (the budget may end the cooldown)
    assert "lll" not in re.sub("lll([gG]{4}|[gG]*$)", "", trace)
    phases = re.findall(r"[pP]+", trace)
    cut = [m.end() for m in re.finditer(r"[pP]+", trace) if trace[m.end() : m.end() + 1] == "R"]
    assert len(phases) >= 8
    for m in re.finditer(r"[pP]+", trace):
        assert len(m.group()) == 3 or m.end() in cut or m.end() == len(trace)  # or the budget
    for m in re.finditer(r"[lL]", trace):  # after a step: a winner's probes, a loser's step
        nxt = trace[m.end() : m.end() + 1]
        if m.group() == "L" and nxt:
            assert nxt in "pPR"
        elif nxt:
            assert nxt in "lLgGR"
    assert "L" in trace and "l" in trace


def test_without_probes_the_option_changes_nothing() -> None:
    a = drive(make_optimizer("hybrid", 3, seed=6, budget=30, confidence=0.0))
    b = drive(make_optimizer("hybrid", 3, seed=6, budget=30, confidence=0.0, probes_per_dim=0.0))
    assert all(np.array_equal(x, y) for x, y in zip(a, b, strict=True))
