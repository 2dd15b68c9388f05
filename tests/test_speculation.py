"""Speculative decisions change when a decision is computed, never what it is."""

from __future__ import annotations

import time

import pytest
import torch

from localpbo_core.optimizers import available_optimizers
from localpbo_core.session import Answer, AnswerKind, Session, Step
from localpbo_core.settings import RunSettings
from localpbo_core.speculation import Speculation, possible_answers, predicted


def _settings(algorithm: str, budget: int = 16, ties: bool = False) -> RunSettings:
    if ties:  # "can't tell" modelled and answered (about a third of the duels)
        return RunSettings(
            algorithm=algorithm,
            problem="hartmann6",
            seed=3,
            budget=budget,
            tie_threshold=0.5,
            indifference=0.1,
        )
    return RunSettings(algorithm=algorithm, problem="hartmann6", seed=3, budget=budget)


def _drive(
    session: Session,
    speculate: bool,
    threaded: bool = False,
    answers: list[Answer] | None = None,
    step: Step | None = None,
) -> list[bytes]:
    """Run to the end with the simulated oracle; with ``speculate`` every last pending duel is
    answered through a :class:`Speculation` whose branch is adopted. Returns every candidate
    (and appends every answer to ``answers`` if given). ``step``: the session's open step, if
    it was asked already (candidates evaluated before it are evaluated again: same seed)."""
    oracle = session.oracle()
    values: dict[int, float] = {}
    for cand in session.optimizer.history.candidates:
        if step is None or all(cand.id != c.id for c in step.candidates):
            values[cand.id] = session.evaluate(cand)
    thetas: list[bytes] = []
    if step is None:
        step = session.ask()
    while step is not None:
        for cand in step.candidates:
            values[cand.id] = session.evaluate(cand)
            thetas.append(cand.theta.tobytes())
        step_next: Step | None = None
        for duel in step.duels:
            first = oracle.judge(duel.duel_id, values[duel.first], values[duel.second])
            if first is None:
                answer = Answer.indifferent(duel)
            else:
                answer = Answer.decisive(duel, duel.first if first else duel.second)
            if answers is not None:
                answers.append(answer)
            if speculate and len(session.pending()) == 1:
                spec = Speculation(session)
                if threaded:
                    spec.start().join()
                else:
                    spec.run()
                branch = spec.take(answer)
                assert branch is not None and branch.verdict.accepted
                session = branch.session
                step_next = branch.step
            else:
                assert session.offer(answer).accepted
                if not session.step_open and not session.done:
                    step_next = session.ask()
        step = step_next
    assert session.done
    return thetas


@pytest.mark.parametrize("algorithm", available_optimizers())
def test_adopted_branches_give_the_same_run(algorithm: str) -> None:
    plain = _drive(Session(_settings(algorithm)), speculate=False)
    speculative = _drive(Session(_settings(algorithm)), speculate=True)
    assert speculative == plain


def test_threaded_speculation_gives_the_same_run() -> None:
    plain = _drive(Session(_settings("turpbo")), speculate=False)
    threaded = _drive(Session(_settings("turpbo")), speculate=True, threaded=True)
    assert threaded == plain


@pytest.mark.parametrize("algorithm", ["turpbo", "prefsqp", "gipbor"])
def test_adopted_branches_with_ties_give_the_same_run(algorithm: str) -> None:
    answers: list[Answer] = []
    plain = _drive(Session(_settings(algorithm, ties=True)), speculate=False, answers=answers)
    assert any(a.kind is AnswerKind.INDIFFERENT for a in answers)
    speculative = _drive(Session(_settings(algorithm, ties=True)), speculate=True)
    assert speculative == plain


def test_the_cant_tell_branch_is_prepared_when_ties_are_modelled() -> None:
    session = _open_session(ties=True)
    spec = Speculation(session)
    spec.run()
    (indifferent,) = [a for a in spec.answers if a.kind is AnswerKind.INDIFFERENT]
    assert spec.ready == spec.answers  # all three answers have a branch
    branch = spec.take(indifferent)
    assert branch is not None and branch.verdict.accepted and branch.step is not None
    # adopting it is offering it directly: same state, same next step, same rest of the run
    direct = session.fork()
    assert direct.offer(indifferent).accepted
    step = direct.ask()
    assert branch.step.duels == step.duels
    assert [c.theta.tobytes() for c in branch.step.candidates] == [
        c.theta.tobytes() for c in step.candidates
    ]
    assert branch.session.accepted == direct.accepted
    assert branch.session.optimizer.ties().tolist() == direct.optimizer.ties().tolist()
    assert _drive(branch.session, False, step=branch.step) == _drive(direct, False, step=step)


def _open_session(algorithm: str = "turpbo", ties: bool = False) -> Session:
    """A session past its initial design with one duel pending."""
    session = Session(_settings(algorithm, ties=ties))
    while session.evaluations < 4:
        step = session.ask()
        for duel in step.duels:
            assert session.offer(Answer.decisive(duel, duel.first)).accepted
    session.ask()
    assert len(session.pending()) == 1
    return session


def test_forks_leave_the_session_untouched() -> None:
    session = _open_session()
    before = (session.evaluations, len(session.accepted), session.pending())
    spec = Speculation(session)
    spec.run()
    assert set(spec.ready) >= set(spec.answers[:2])
    assert (session.evaluations, len(session.accepted), session.pending()) == before
    # every branch decided on its own answer: different next candidates
    a, b = (spec.take(x) for x in spec.answers[:2])
    assert a is not None and b is not None and a.step is not None and b.step is not None
    assert a.session.accepted[-1] == spec.answers[0]
    assert b.session.accepted[-1] == spec.answers[1]


def test_a_refused_answer_has_no_branch() -> None:
    session = _open_session()
    spec = Speculation(session)
    spec.run()
    indifferent = spec.answers[2]
    accepted = session.fork().offer(indifferent).accepted
    assert (spec.take(indifferent) is not None) == accepted
    other = session.fork()
    duel = session.pending()[0]
    stranger = Answer(duel.duel_id, duel.second, duel.first, indifferent.kind)
    assert spec.take(stranger) is None
    assert other.offer(stranger).accepted is False


def test_take_waits_for_the_branch_being_computed() -> None:
    session = _open_session()
    spec = Speculation(session).start()
    while not spec.ready and spec.computing is None:
        time.sleep(0.001)
    branch = spec.take(spec.answers[0])  # computed first: running or ready, never skipped
    spec.join()
    assert branch is not None and branch.step is not None
    assert spec.ready == (spec.answers[0],)  # take() cancelled the others


def test_cancel_stops_before_the_next_branch() -> None:
    session = _open_session()
    spec = Speculation(session)
    spec.cancel()
    spec.run()
    assert spec.ready == ()


def test_needs_exactly_one_pending_duel() -> None:
    session = Session(_settings("turpbo"))
    with pytest.raises(ValueError, match="exactly one pending duel"):
        possible_answers(session)


def test_speculation_computes_the_current_recommendation_on_a_fork() -> None:
    session = _open_session("turpbo")
    before = len(session.accepted)
    spec = Speculation(session, recommend=True)
    spec.run()
    expected = session.recommendation()
    assert spec.recommendation is not None and expected is not None
    assert spec.recommendation.id == expected.id and len(session.accepted) == before
    cancelled = Speculation(session, recommend=True)
    cancelled.cancel()
    cancelled.run()
    assert cancelled.recommendation is None


def test_branches_are_prepared_most_likely_first() -> None:
    session = _open_session(ties=True)
    surrogate = session.optimizer.surrogate
    assert surrogate is not None
    probs = predicted(session)
    assert probs is not None and abs(sum(probs) - 1.0) < 1e-9 and min(probs) >= 0
    duel = session.pending()[0]
    a = torch.tensor(session.candidate(duel.first).theta)
    b = torch.tensor(session.candidate(duel.second).theta)
    assert probs[0] == pytest.approx(float(surrogate.preference_probability(a, b)))
    assert probs[2] == pytest.approx(float(surrogate.tie_probability(a, b)))
    seen: list[Answer] = []
    spec = Speculation(session, on_branch=lambda branch: seen.append(branch.answer))
    assert set(spec.answers) == set(possible_answers(session))
    assert spec.probabilities == tuple(sorted(probs, reverse=True))
    spec.run()
    assert seen == list(spec.answers)  # computed and handed over in that order
    by_probability = dict(zip(possible_answers(session), probs, strict=True))
    assert spec.answers[0] == max(by_probability, key=lambda a: by_probability[a])


def test_without_a_model_the_order_is_first_second_cant_tell() -> None:
    session = Session(_settings("sobol", ties=True))
    step = session.ask()
    while len(session.pending()) != 1:
        assert session.offer(Answer.decisive(step.duels[0], step.duels[0].first)).accepted
    assert predicted(session) is None
    spec = Speculation(session)
    assert spec.answers == possible_answers(session) and spec.probabilities is None
