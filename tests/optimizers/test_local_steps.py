"""The local methods' options beyond the paper leave the paper's runs unchanged, and GIPBO's
duel-gated step (``accept_step="duel"``) keeps a step only when it wins its duel."""

from __future__ import annotations

import gzip
import json
from pathlib import Path

import numpy as np
import pytest

from localpbo_core.loop import run_session
from localpbo_core.optimizers import Outcome, make_optimizer
from localpbo_core.session import Session
from localpbo_core.settings import RunSettings

ROOT = Path(__file__).resolve().parents[2]
STORED = ROOT / "docs" / "results" / "synthetic" / "runs"


@pytest.mark.parametrize("algorithm", ["prefsqp", "gipbo"])
def test_default_candidates_match_the_stored_paper_run(algorithm: str) -> None:
    path = STORED / f"hartmann6__{algorithm}__seed0.json.gz"
    assert path.exists(), f"the stored run {path.name} is part of the repository"
    with gzip.open(path, "rt") as fh:
        stored = json.load(fh)
    settings = stored["settings"]
    assert settings["optimizer_options"] == {}
    session = Session(
        RunSettings(
            algorithm=algorithm,
            problem="hartmann6",
            seed=0,
            initial_design=settings["initial_design"],
            noise_fraction=settings["noise_fraction"],
        )
    )
    trace = run_session(session)
    got = np.array([trace.native[i] for i in sorted(trace.native)])
    want = np.array([c["native"] for c in stored["candidates"]])
    assert got.shape == want.shape
    # the stored runs were made by another process; BLAS round-off differs in the last bits
    # (measured: at most 6e-9 on these runs), a changed rule moves candidates by far more
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-6)


def _older_wins(opt: object) -> None:
    while not opt.done:  # type: ignore[attr-defined]
        ask = opt.ask()  # type: ignore[attr-defined]
        opt.tell(  # type: ignore[attr-defined]
            [Outcome(min(d.first, d.second), max(d.first, d.second)) for d in ask.duels]
        )


@pytest.mark.parametrize("algorithm", ["gipbo", "gipbor"])
def test_gipbo_gated_step_is_rejected_when_it_loses(algorithm: str) -> None:
    # every newer candidate loses its duel: gated steps never move the center
    gated = make_optimizer(algorithm, 2, seed=0, budget=24, accept_step="duel")
    _older_wins(gated)
    assert len(gated.centers) >= 3
    assert all(np.array_equal(c, gated.centers[0]) for c in gated.centers)
    assert gated.gradient_steps == 0
    plain = make_optimizer(algorithm, 2, seed=0, budget=24)
    _older_wins(plain)
    assert any(not np.array_equal(c, plain.centers[0]) for c in plain.centers)


def test_gipbo_gated_step_is_kept_when_it_wins_and_improves() -> None:
    def quad(t: np.ndarray) -> float:
        return float(-np.sum((np.asarray(t) - 0.3) ** 2))

    from optim_helpers import drive

    gaps = []
    for seed in (1, 2):
        opt = make_optimizer("gipbor", 2, seed=seed, budget=22, accept_step="duel")
        vals = np.array([quad(t) for t in drive(opt, quad)])
        gaps.append(1.0 - vals.max() / vals[:2].max())
        # each center is an evaluated candidate (a winning trial point or a phase's winner)
        ids = {c.theta.tobytes() for c in opt.history.candidates}
        assert all(c.tobytes() in ids for c in opt.centers)
    assert np.mean(gaps) >= 0.5, gaps


@pytest.mark.parametrize(
    ("algorithm", "options"),
    [
        ("prefsqp", {"accept_step": "duel"}),
        ("prefsqp", {"line_search": "duel"}),
        ("gipbor", {"accept_step": "duel"}),
    ],
)
def test_a_cant_tell_answer_rejects_a_gated_step(algorithm: str, options: dict) -> None:
    from localpbo_core.optimizers import Indifferent

    opt = make_optimizer(algorithm, 2, seed=1, budget=20, tie_threshold=0.5, **options)
    trials = 0
    while not opt.done:
        ask = opt.ask()
        trial = opt._trial_active  # type: ignore[attr-defined]
        if trial:  # the gated step's duels: "can't tell", no win
            trials += 1
            opt.tell([Indifferent(d.first, d.second) for d in ask.duels])
        else:  # the phase's own duels: the older candidate wins
            opt.tell([Outcome(min(d.first, d.second), max(d.first, d.second)) for d in ask.duels])
    assert trials >= 2
    assert all(np.array_equal(c, opt.centers[0]) for c in opt.centers)  # type: ignore[attr-defined]
    assert len(opt.ties()) >= trials
