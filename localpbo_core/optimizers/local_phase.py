"""Shared bookkeeping of the derivative-informed local methods GIPBO, GIPBOr and PrefSQP
(paper Sec. 5.1-5.2, App. C.2-C.4) and their budget accounting (App. D.1).

An iteration ("phase") has a center ``x_t``. The first center is the winner of the initial
design. After a step to ``x_{t+1}`` the new center is evaluated but NOT dueled at that moment:
it is registered together with the first local query(ies) of the next phase, which are
dueled against it (App. D.1: "the subsequent center updates are not immediately evaluated",
i.e. not immediately compared). So with ``G`` evaluated step centers, ``N`` evaluations give
``N - 1 - G`` comparisons (the initial pair gives one comparison for two evaluations; the
paper's ``N - G`` counts the same way as its ``N - 1`` for king-of-the-hill methods, off by
the initial pair). Exception: if a step center would be the very last evaluation of the
budget, it is dueled against the current incumbent (an ask needs a duel), one extra
comparison.

A step that lands (within ``DUPLICATE_ATOL``) on the old center reuses it (no evaluation).

The reported incumbent (``PreferenceOptimizer.incumbent``) is the current local incumbent:
the latest winner of the phase's duel chain.

Duel-gated steps (an option of the subclasses, beyond the paper; off by default): instead of
moving to the step's point ``x'`` unconditionally, a subclass calls :meth:`_ask_trial` with
one or more trial points. The next ask evaluates them and duels each against the local
incumbent ``x*`` (the king of the phase's duel chain: ``x_t`` unless a local query beat it).
If some trial point wins, the next center is the winner (with several winners, the one of
highest posterior mean under a refit on every duel, ties to the lowest id); it is already
evaluated, so no step center is pending. If none wins, the step is rejected and the next
phase starts at ``x*``. The trial points are the phase's last queries: ``N`` evaluations then
give ``N - 1 - G`` comparisons as before, ``G`` counting only the ungated step centers.
"""

from __future__ import annotations

import abc
from collections.abc import Mapping, Sequence
from typing import Unpack

import numpy as np
import torch

from localpbo_core.optimizers.base import Ask, Candidate, Duel, DuelAnswer, Outcome
from localpbo_core.optimizers.preference_optimizer import PreferenceOptimizer, RunOptions
from localpbo_core.optimizers.surrogate_refit import SurrogateRefitter
from localpbo_core.surrogate import Surrogate
from localpbo_core.surrogate.data import DUPLICATE_ATOL


class LocalPhaseOptions(RunOptions, total=False):
    """:class:`RunOptions` and the ``hyperparameters`` of :class:`LocalPhaseOptimizer`."""

    hyperparameters: Mapping[str, object] | None


class LocalPhaseOptimizer(PreferenceOptimizer):
    """Base of the center-based local methods (see the module docstring).

    Subclasses implement :meth:`_local_thetas` (the queries of the current ask),
    :meth:`_local_opponent` and :meth:`_after_duels`; they call :meth:`_move_center` to end a
    phase.
    """

    def __init__(
        self,
        dim: int,
        seed: int,
        budget: int,
        hyperparameters: Mapping[str, object] | None = None,
        **run: Unpack[RunOptions],
    ) -> None:
        super().__init__(dim, seed, budget, **run)
        self._refitter = SurrogateRefitter.for_options(
            1, hyperparameters, self.dim, self.tie_threshold
        )
        self._center_id: int | None = None
        self._center_theta: np.ndarray | None = None
        self._center_pending = False  # a step center not evaluated yet
        self._local_inc_id: int | None = None  # None while the center is pending
        self._final_center_duel = False
        self._trial_thetas: list[np.ndarray] | None = None  # gated step points to ask next
        self._trial_active = False  # the open ask is a trial ask
        self._surrogate: Surrogate | None = None
        self._fit_key: tuple[int, int] | None = None
        #: Number of steps whose new center was evaluated (``G`` of App. D.1).
        self.gradient_steps = 0
        #: Centers of every phase, in order (thetas).
        self.centers: list[np.ndarray] = []

    # ------------------------------------------------------------------ state
    @property
    def center(self) -> np.ndarray | None:
        """The current center ``x_t`` (possibly not evaluated yet)."""
        return self._center_theta

    @property
    def surrogate(self) -> Surrogate | None:
        """The last fitted surrogate."""
        return self._surrogate

    def _local_incumbent_theta(self) -> np.ndarray:
        """Theta of the local incumbent (the pending center before it is evaluated)."""
        if self._local_inc_id is None:
            assert self._center_theta is not None
            return self._center_theta
        return np.array(self._candidates[self._local_inc_id].theta)

    def _fit(self) -> Surrogate:
        """Refit the pairwise GP on all duels, hyperparameters learned (warm-started from the
        previous fit) unless fixed by the ``hyperparameters`` option
        (:mod:`.surrogate_refit`). Reuses the previous fit when no candidate or duel was
        added."""
        key = (len(self._candidates), len(self._outcomes))
        if self._surrogate is not None and key == self._fit_key:
            return self._surrogate
        self._fit_key = key
        fitted = self._refitter.refit(self.train_inputs(), self.comparisons(), self.ties())
        self._surrogate = fitted
        return fitted

    # ------------------------------------------------------------------ ask
    def _propose(self, remaining: int) -> Ask:
        if self._center_theta is None:  # first phase: the winner of the initial design
            self._center_id = self._require_incumbent()
            self._center_theta = np.array(self._candidates[self._center_id].theta)
            self._local_inc_id = self._center_id
            self.centers.append(self._center_theta.copy())
            self._start_phase()
        if self._trial_thetas is not None:
            trial = self._register(self._trial_thetas[:remaining])
            self._trial_thetas = None
            self._trial_active = True
            inc = self._require_incumbent()
            return Ask(tuple(trial), tuple(Duel(c.id, inc) for c in trial))
        if self._center_pending and remaining == 1:
            new = self._register([self._center_theta])
            self._center_id = new[0].id
            self._center_pending = False
            self.gradient_steps += 1
            self._final_center_duel = True
            return Ask(tuple(new), (Duel(new[0].id, self._require_incumbent()),))
        budget_for_queries = remaining - (1 if self._center_pending else 0)
        thetas = self._local_thetas(budget_for_queries)
        registered: list[Candidate] = []
        if self._center_pending:
            registered += self._register([self._center_theta])
            self._center_id = registered[0].id
            self._local_inc_id = self._center_id
            self._center_pending = False
            self.gradient_steps += 1
        queries = self._register(thetas)
        registered += queries
        opp = self._local_opponent()
        return Ask(tuple(registered), tuple(Duel(q.id, opp) for q in queries))

    def _move_center(self, new_theta: np.ndarray) -> None:
        """Start the next phase at ``Pi_Theta(new_theta)`` (evaluated with the next ask)."""
        new_theta = np.clip(np.asarray(new_theta, dtype=np.float64), 0.0, 1.0)
        assert self._center_theta is not None
        if np.max(np.abs(new_theta - self._center_theta)) > DUPLICATE_ATOL:
            self._center_theta = new_theta
            self._center_pending = True
            self._local_inc_id = None
        else:
            self._local_inc_id = self._center_id
        self.centers.append(self._center_theta.copy())
        self._start_phase()

    def _ask_trial(self, thetas: Sequence[np.ndarray]) -> None:
        """End the phase with a duel-gated step (module docstring): the next ask evaluates
        ``thetas`` (clipped to the cube; points within ``DUPLICATE_ATOL`` of the center are
        dropped) and duels each against the local incumbent. Without any point left the
        phase restarts at the local incumbent."""
        assert self._center_theta is not None
        pts = [np.clip(np.asarray(t, dtype=np.float64), 0.0, 1.0) for t in thetas]
        pts = [t for t in pts if np.max(np.abs(t - self._center_theta)) > DUPLICATE_ATOL]
        if not pts:
            self._adopt_center(self._require_incumbent())
            return
        self._trial_thetas = pts

    def _adopt_center(self, candidate_id: int) -> None:
        """Start the next phase at the evaluated candidate ``candidate_id`` (it becomes the
        center and the local incumbent; no step center is pending)."""
        self._center_id = int(candidate_id)
        self._center_theta = np.array(self._candidates[candidate_id].theta)
        self._center_pending = False
        self._local_inc_id = self._center_id
        self._set_incumbent(self._center_id)
        self.centers.append(self._center_theta.copy())
        self._start_phase()

    def _after_trial(
        self, candidates: tuple[Candidate, ...], outcomes: tuple[DuelAnswer, ...]
    ) -> None:
        """Accept the best winning trial point or reject the step (module docstring). A
        "can't tell" answer is no win."""
        inc = self._require_incumbent()
        ids = {c.id for c in candidates}
        winners = sorted(
            o.winner
            for o in outcomes
            if isinstance(o, Outcome) and o.loser == inc and o.winner in ids
        )
        if not winners:
            self._adopt_center(inc)
            return
        best = winners[0]
        if len(winners) > 1:
            surrogate = self._fit()
            X = torch.tensor(
                np.stack([self._candidates[w].theta for w in winners]), dtype=torch.float64
            )
            with torch.no_grad():
                best = winners[int(torch.argmax(surrogate.mean(X)))]
        self._adopt_center(best)

    def _on_step_complete(
        self, candidates: tuple[Candidate, ...], outcomes: tuple[DuelAnswer, ...]
    ) -> None:
        if self._trial_active:
            self._trial_active = False
            self._after_trial(candidates, outcomes)
            return
        if self._final_center_duel:  # the last evaluation: center vs the incumbent
            self._final_center_duel = False
            self._update_king(outcomes)
            return
        self._after_duels(candidates, outcomes)

    # ------------------------------------------------------------------ subclass API
    def _start_phase(self) -> None:
        """Reset per-phase counters (called when a phase starts)."""

    @abc.abstractmethod
    def _local_thetas(self, remaining: int) -> list[np.ndarray]:
        """The queries of this ask (``1 <= len <= remaining``)."""

    @abc.abstractmethod
    def _after_duels(
        self, candidates: tuple[Candidate, ...], outcomes: tuple[DuelAnswer, ...]
    ) -> None:
        """Update the phase after every duel of a local ask was answered."""

    @abc.abstractmethod
    def _local_opponent(self) -> int:
        """Candidate id the queries of this ask are dueled against (called after the
        pending center, if any, has been registered)."""
