"""The ask/tell contract: the values exchanged between an optimizer and its caller.

An optimizer is a deterministic state machine over (config, seed, outcomes so far), so the
same configuration and the same outcomes in the same order reproduce the same state:
``ask()`` returns new candidates to evaluate and the duels wanted between candidate ids;
``tell()`` takes duel outcomes: decisive (:class:`Outcome`) or, when the optimizer was built
with ``tie_threshold > 0``, "can't tell" (:class:`Indifferent`). Budget is counted in
evaluations (paper App. D.1).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass(frozen=True)
class Candidate:
    """A parameter vector to evaluate. ``theta`` lies in [0,1]^d (float64, read-only)."""

    id: int
    theta: np.ndarray = field(compare=False)


@dataclass(frozen=True)
class Duel:
    """A comparison wanted between two candidate ids (new or earlier ones)."""

    first: int
    second: int


@dataclass(frozen=True)
class Ask:
    """The next work: candidates to evaluate (possibly none) and duels to run."""

    candidates: tuple[Candidate, ...]
    duels: tuple[Duel, ...]


@dataclass(frozen=True)
class Outcome:
    """The result of a duel: ``winner`` was preferred over ``loser`` (ids)."""

    winner: int
    loser: int


@dataclass(frozen=True)
class Indifferent:
    """A "can't tell" answer to the duel between ``first`` and ``second`` (ids): neither was
    preferred. Modelled by the ordinal likelihood with threshold ``tie_threshold``
    (:mod:`localpbo_core.surrogate.ordinal`); accepted only when that threshold is > 0."""

    first: int
    second: int


DuelAnswer = Outcome | Indifferent
"""What ``tell`` accepts for one duel."""
