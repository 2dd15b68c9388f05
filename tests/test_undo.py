"""A person's undo at the library level: :meth:`Session.retract` returns the run to the state it
had before the answer, so a retracted answer followed by another one gives the run that only
ever got the other one (θ for θ, answer for answer), with fresh ids for whatever was discarded.
"""

from __future__ import annotations

import numpy as np
import pytest

from localpbo_core.session import Answer, Reason, Session, Step
from localpbo_core.settings import RunSettings

SETTINGS = RunSettings(
    algorithm="turpbo", problem="hartmann6", seed=5, budget=14, tie_threshold=0.5
)


def _answer(session: Session, values: dict[int, float], duel_index: int) -> Answer:
    """The rule of these tests: the higher value wins; every fifth duel "can't tell"."""
    duel = session.pending()[0]
    if duel_index % 5 == 4:
        return Answer.indifferent(duel)
    winner = duel.first if values[duel.first] >= values[duel.second] else duel.second
    return Answer.decisive(duel, winner)


def _flip(answer: Answer) -> Answer:
    duel = _duel(answer)
    if answer.winner == answer.first:
        return Answer.decisive(duel, answer.second)
    return Answer.decisive(duel, answer.first)


def _duel(answer: Answer):  # type: ignore[no-untyped-def]
    from localpbo_core.session import DuelRequest

    return DuelRequest(answer.duel_id, answer.first, answer.second)


def _run(undo_at: dict[int, int], flip_at: set[int], undo_depth: int = 8) -> dict[str, object]:
    """Run to the end; at answer number ``k`` in ``undo_at`` first give the flipped answer and
    ``undo_at[k]`` later answers, then retract them all (latest first) and go on with the rule's
    answers; at ``k`` in ``flip_at`` the flipped answer is the one kept."""
    session = Session(SETTINGS, undo_depth=undo_depth)
    values: dict[int, float] = {}
    proposed: list[tuple[int, bytes]] = []

    def evaluate(step: Step) -> None:
        for cand in step.candidates:
            values[cand.id] = session.evaluate(cand)
            proposed.append((cand.id, cand.theta.tobytes()))

    evaluate(session.ask())
    k = 0
    while not session.done:
        answer = _answer(session, values, k)
        if k in flip_at and answer.winner is not None:
            answer = _flip(answer)
        if k in undo_at:
            wrong = [_flip(answer) if answer.winner is not None else answer]
            assert session.offer(wrong[0]).accepted
            if not session.step_open:
                evaluate(session.ask())
            for j in range(undo_at[k]):  # more answers given after the wrong one
                more = _answer(session, values, k + 1 + j)
                assert session.offer(more).accepted
                wrong.append(more)
                if not session.step_open and not session.done:
                    evaluate(session.ask())
            for taken in reversed(wrong):
                verdict = session.retract(taken.duel_id)
                assert verdict.reason is Reason.RETRACTED, verdict
            assert session.pending()[0].duel_id == answer.duel_id
        assert session.offer(answer).accepted
        k += 1
        if not session.step_open and not session.done:
            evaluate(session.ask())
    history = session.optimizer.history
    return {
        "session": session,
        "proposed": proposed,
        "thetas": [c.theta.tobytes() for c in history.candidates],
        "outcomes": [type(o).__name__ for o in history.outcomes],
        "accepted": [(a.kind, a.winner is None) for a in session.accepted],
    }


def test_undo_then_another_answer_is_the_run_that_only_got_the_other_answer() -> None:
    plain = _run({}, set())
    flipped = _run({}, {7})
    undone = _run({7: 0}, set())
    # retracting the flipped answer and giving the rule's: the plain run, state for state
    assert undone["thetas"] == plain["thetas"] and undone["outcomes"] == plain["outcomes"]
    assert undone["thetas"] != flipped["thetas"]  # the answer mattered: the test can fail
    kept = [t for _, t in undone["proposed"]]
    assert set(plain["thetas"]) <= set(kept)
    # ids: the discarded candidate's id stays spent, so the run reissues none
    ids = [cid for cid, _ in undone["proposed"]]
    assert len(ids) == len(set(ids)) == len(plain["thetas"]) + 1
    session = undone["session"]
    assert isinstance(session, Session)
    assert session.spent_ids[0] == len(plain["thetas"]) + 1


def test_undo_three_answers_back_including_ties_and_completed_asks() -> None:
    plain = _run({}, set())
    undone = _run({6: 3}, set())  # answers 6, 7, 8 and 9 (a "can't tell") taken back
    assert undone["thetas"] == plain["thetas"] and undone["outcomes"] == plain["outcomes"]
    assert undone["accepted"] == plain["accepted"]


def _open(undo_depth: int = 2) -> tuple[Session, dict[int, float]]:
    session = Session(SETTINGS, undo_depth=undo_depth)
    values: dict[int, float] = {}
    for _ in range(8):
        if not session.step_open:
            for cand in session.ask().candidates:
                values[cand.id] = session.evaluate(cand)
        assert session.offer(_answer(session, values, 0)).accepted
    if not session.step_open:
        for cand in session.ask().candidates:
            values[cand.id] = session.evaluate(cand)
    return session, values


def _state(session: Session) -> tuple[object, ...]:
    h = session.optimizer.history
    return (
        [c.theta.tobytes() for c in h.candidates],
        len(h.outcomes),
        session.pending(),
        list(session.accepted),
        session.spent_ids,
    )


def test_refused_retractions_change_nothing() -> None:
    session, _ = _open()
    before = _state(session)
    last = session.accepted[-1].duel_id
    for duel_id, why in [
        (last - 1, "not the latest"),
        (session.pending()[0].duel_id, "no accepted answer"),
        (10_000, "no accepted answer"),
    ]:
        verdict = session.retract(duel_id)
        assert verdict.reason is Reason.RETRACTION_REFUSED and why in verdict.detail
        assert _state(session) == before
    assert session.undoable() == 2
    assert session.retract(last).reason is Reason.RETRACTED
    assert session.retract(last - 1).reason is Reason.RETRACTED
    exhausted = _state(session)
    verdict = session.retract(last - 2)  # undo_depth = 2
    assert verdict.reason is Reason.RETRACTION_REFUSED and "last 2" in verdict.detail
    assert _state(session) == exhausted
    fresh = Session(SETTINGS, undo_depth=2)
    assert fresh.retract(0).reason is Reason.RETRACTION_REFUSED
    no_undo = Session(SETTINGS)
    for cand in no_undo.ask().candidates:
        no_undo.evaluate(cand)
    duel = no_undo.pending()[0]
    assert no_undo.offer(Answer.decisive(duel, duel.first)).accepted
    assert no_undo.retract(duel.duel_id).reason is Reason.RETRACTION_REFUSED


def test_withdrawn_duels_are_refused_and_their_ids_never_reused() -> None:
    session, _ = _open()
    answered = session.accepted[-1]
    withdrawn = session.pending()
    spent = session.spent_ids
    assert session.retract(answered.duel_id).reason is Reason.RETRACTED
    assert session.pending()[0].duel_id == answered.duel_id
    for duel in withdrawn:
        verdict = session.offer(Answer.decisive(duel, duel.first))
        assert verdict.reason is Reason.WITHDRAWN
        with pytest.raises(KeyError):
            session.candidate(max(duel.first, duel.second))
    assert session.offer(_flip(answered)).accepted
    step = session.ask()
    assert min(c.id for c in step.candidates) >= spent[0]
    assert min(d.duel_id for d in step.duels) >= spent[1]
    for cand in step.candidates:  # run ids map back onto the optimizer's candidates
        np.testing.assert_array_equal(session.candidate(cand.id).theta, cand.theta)
    assert session.incumbent is not None and session.incumbent.id in {
        answered.first,
        answered.second,
        *(c.id for c in step.candidates),
        *range(spent[0]),
    }


def test_undo_depth_is_checked() -> None:
    from localpbo_core.settings import SettingError

    with pytest.raises(SettingError) as err:
        Session(SETTINGS, undo_depth=-1)
    assert err.value.field == "undo_depth"
