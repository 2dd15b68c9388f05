"""qEUBO baseline (paper Sec. 6, App. D.1 baselines; Lin et al. 2022, Astudillo et al. 2023).

Each iteration refits the pairwise GP (learned hyperparameters, warm-started from the previous
fit; shared PairwiseGP settings of App. D.1) and maximises BoTorch's acquisition over
[0,1]^d with ``optimize_acqf`` (5 restarts, 1024 raw samples), driven on our surrogate
through :class:`~localpbo_core.optimizers.botorch_adapter.SurrogateModel`:

* ``q = 1`` (default, the paper's setting): analytic EUBO against the previous winner,
  ``EUBO(x) = E[max(f(x), f(x*))] - m* = s (phi(z) + z Phi(z))``, ``z = (m - m*) / s``,
  ``s^2 = Var[f(x) - f(x*)]`` (``AnalyticExpectedUtilityOfBestOption(previous_winner=x*)``);
  the new point is dueled against the incumbent (king of the hill, App. D.1).
* ``q > 1``: Monte Carlo ``qEUBO(x_1..x_q) = E[max_j f(x_j)]`` over the q new points alone
  (``qExpectedUtilityOfBestOption``, Sobol QMC base samples seeded per step), as in
  Astudillo et al. where the decision maker picks the best of the q shown options.

Comparison protocol for ``q > 1`` (a decision of this package, documented in the README): the
best of the q new points is found by a single-elimination bracket of pairwise duels among
them (round 1 pairs ``(c1, c2), (c3, c4), ...``; winners meet in the next round; an odd
one out gets a bye), i.e. ``q - 1`` duels, one ask per round (follow-up asks carry no new
candidates). The bracket winner is then dueled once against the incumbent and replaces it if
it wins. So ``q`` evaluations cost exactly ``q`` comparisons: the App. D.1 accounting (one
comparison per new evaluation, ``2 + 10d`` evaluations -> ``1 + 10d`` comparisons) holds for
every q. With noise-free preferences the bracket returns qEUBO's "best of q" response.
When fewer than q evaluations remain, the last batch is smaller (q = 1 uses EUBO).

Determinism: the acquisition seed of step ``t`` comes from ``step_generator(seed, t)``; it
seeds the QMC sampler, ``optimize_acqf``'s raw samples and (through BoTorch's
``manual_seed`` context, which restores torch's global RNG state afterwards) the Boltzmann
selection of initial conditions that BoTorch draws from torch's global RNG.
"""

from __future__ import annotations

from typing import Unpack

import numpy as np
import torch
from botorch.acquisition import AcquisitionFunction
from botorch.acquisition.preference import (
    AnalyticExpectedUtilityOfBestOption,
    qExpectedUtilityOfBestOption,
)
from botorch.optim import optimize_acqf
from botorch.sampling import SobolQMCNormalSampler
from botorch.utils.sampling import manual_seed

from localpbo_core.optimizers.base import Ask, Candidate, Duel, DuelAnswer, Outcome
from localpbo_core.optimizers.botorch_adapter import SurrogateModel
from localpbo_core.optimizers.gp_acquisition import GPAcquisitionOptimizer, GPAcquisitionOptions
from localpbo_core.optimizers.preference_optimizer import step_generator
from localpbo_core.validation import check_int


class QEUBO(GPAcquisitionOptimizer):
    """qEUBO / EUBO-against-the-previous-winner baseline behind the ask/tell contract.

    Args:
        dim, seed, budget, initial_design, warm_start, hyperparameter_refit_every,
            hyperparameters: see ``GPAcquisitionOptimizer``.
        batch_size: q >= 1 new points per iteration (paper: 1; App. D.7 also 2 and 4).
        num_raw_samples: ``optimize_acqf`` raw samples (shared PairwiseGP table: 1024).
        num_restarts: ``optimize_acqf`` restarts (table: 5).
        num_mc_samples: QMC base samples of qEUBO for q > 1.
    """

    name = "qeubo"

    def __init__(
        self,
        dim: int,
        seed: int,
        budget: int,
        num_mc_samples: int = 256,
        **options: Unpack[GPAcquisitionOptions],
    ) -> None:
        super().__init__(dim, seed, budget, **options)
        self.num_mc_samples = check_int("num_mc_samples", num_mc_samples)
        # Bracket state for q > 1: survivors of the current round and the next duels.
        self._survivors: list[int] = []
        self._next_duels: list[Duel] = []
        self._final_pending = False

    # ------------------------------------------------------------------ state
    @property
    def done(self) -> bool:
        """True when the budget is spent and no duel is pending or still to be asked."""
        return super().done and not self._next_duels

    # ------------------------------------------------------------------ ask
    def ask(self) -> Ask:
        """Next work; follow-up rounds of a q > 1 bracket are asks without candidates."""
        if self._next_duels and not self.pending_duels:
            duels = tuple(self._next_duels)
            self._next_duels = []
            return self._open_step(Ask((), duels))
        return super().ask()

    def select(self, q: int, rng: np.random.Generator) -> np.ndarray:
        """Refit and maximise (q)EUBO over [0,1]^d; returns ``(q, d)``."""
        surrogate = self._fit()
        model = SurrogateModel(surrogate)
        seed = int(rng.integers(0, 2**31 - 1))
        acq: AcquisitionFunction
        if q == 1:
            inc = self._candidates[self._require_incumbent()].theta
            acq = AnalyticExpectedUtilityOfBestOption(
                pref_model=model,
                previous_winner=torch.tensor(inc, dtype=torch.float64)[None, :],
            )
        else:
            sampler = SobolQMCNormalSampler(torch.Size([self.num_mc_samples]), seed=seed)
            acq = qExpectedUtilityOfBestOption(pref_model=model, sampler=sampler)
        bounds = torch.stack(
            [torch.zeros(self.dim, dtype=torch.float64), torch.ones(self.dim, dtype=torch.float64)]
        )
        # BoTorch picks initial conditions with torch's global RNG (Boltzmann sampling):
        # ``manual_seed`` seeds it for this call only and restores the previous state.
        with manual_seed(seed):
            cand, _ = optimize_acqf(
                acq,
                bounds=bounds,
                q=q,
                num_restarts=self.num_restarts,
                raw_samples=self.num_raw_samples,
                options={"seed": seed},
            )
        return cand.detach().numpy().reshape(q, self.dim)

    def _propose(self, remaining: int) -> Ask:
        q = min(self.batch_size, remaining)
        thetas = self.select(q, step_generator(self.seed, self._step))
        new = self._register(list(thetas))
        if q == 1:
            self._survivors = []
            self._final_pending = True
            return Ask(tuple(new), (Duel(new[0].id, self._require_incumbent()),))
        self._survivors = [c.id for c in new]
        self._final_pending = False
        return Ask(tuple(new), self._round_duels())

    def _round_duels(self) -> tuple[Duel, ...]:
        s = self._survivors
        return tuple(Duel(s[i], s[i + 1]) for i in range(0, len(s) - 1, 2))

    def _on_step_complete(
        self, candidates: tuple[Candidate, ...], outcomes: tuple[DuelAnswer, ...]
    ) -> None:
        if self._final_pending:
            self._final_pending = False
            self._update_king(outcomes)
            return
        losers = {o.loser for o in outcomes if isinstance(o, Outcome)}
        s = self._survivors
        # Winners of the played pairs (in bracket order) plus the bye, if any; after a "can't
        # tell" answer the pair's first candidate (the lower id) goes on.
        nxt = [b if a in losers else a for a, b in zip(s[0::2], s[1::2], strict=False)]
        if len(s) % 2 == 1:
            nxt.append(s[-1])
        self._survivors = nxt
        if len(nxt) > 1:
            self._next_duels = list(self._round_duels())
        else:
            self._final_pending = True
            self._next_duels = [Duel(nxt[0], self._require_incumbent())]
