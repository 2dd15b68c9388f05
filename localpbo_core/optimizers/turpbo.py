"""TuRPBO: trust-region preferential BO (paper Sec. 5.3, App. C.5, Alg. TurPBO).

Each iteration: refit the pairwise GP (learned hyperparameters, warm-started from the
previous fit), build TuRBO's lengthscale-weighted box of side L around the trust-region
center, select q candidates in the box by Thompson sampling (default; pathwise sample
paths, TuRBO perturbation masks, 1024 raw samples, 5 L-BFGS-B restarts; or, with
``acquisition="ts_discrete"``, the best raw candidate per path as in TuRBO), (q)EUBO or
expected improvement (EI, App. D.7 ablation), and duel every candidate against the center.

EI (``acquisition="ei"``): ``EI(x) = E[max(f(x) - mu(x_inc), 0)] = (m - m*) Phi(z) + s
phi(z)`` with ``m = mu(x)``, ``s^2 = var f(x)`` the marginal Laplace posterior of the latent
utility (paper Sec. 4), ``z = (m - m*) / s`` and ``m* = mu(x_inc)`` the posterior mean at
the current incumbent ``x_inc``, the preference-defined best (the king of the hill,
:attr:`PreferenceOptimizer.incumbent`; it is the trust-region center except after a
restart). The utility is observed only through duels, so the incumbent's posterior mean
stands in for the unobserved "best value". EI is maximised in the trust-region box with the
raw-sample + multi-start L-BFGS-B scheme of the Thompson route (gradients by autograd).
EI has no batch form here: ``acquisition="ei"`` with ``batch_size > 1`` is refused
(``SettingError`` on ``batch_size``). It is kept for the App. D.7 ablation, not recommended:
duels inform differences only, so ``s`` keeps its prior value in the direction of the
utility's level, also at the incumbent, where EI is then ``s phi(0)``; unless some point's mean
exceeds ``m*`` by enough, the maximiser is the incumbent itself and TuRPBO duels near-copies
(measured on 32-D GP paths, see ``docs/results/notes.md``). EI of the difference ``f(x) -
f(x_inc)`` under the joint posterior avoids this, but equals EUBO against the incumbent minus
``E[f(x_inc)]``: the ``"qeubo"`` acquisition with q = 1.

Success iff some candidate wins (App. C.5); the counters and L follow
:class:`~localpbo_core.optimizers.trust_region.TrustRegionState`.

Decisions not fixed by the paper (documented here, in the README and the report):

* Several winners in one batch: the first winner in proposal order (lowest id) becomes
  the new center/incumbent (no extra comparisons).
* Restart (L < L_min): all comparison data is kept (the GP is refit on everything); the
  next ask proposes one fresh uniform point (seed-derived), dueled against the global
  incumbent; it becomes the center of a new region of side L_init. While the center is not
  the global incumbent, candidates are dueled against the center (TuRBO's local success
  test) and each new center is additionally dueled once against the global incumbent in
  the next ask ("challenge" duel: one extra comparison, no extra evaluation), so the
  reported incumbent remains the preference-defined king of the hill. Without restarts
  every comparison is exactly a candidate against the incumbent (App. D.1 accounting).
"""

from __future__ import annotations

from typing import Unpack

import numpy as np
import torch

from localpbo_core.optimizers.acquisition import (
    ei_batch,
    eubo_batch,
    thompson_batch,
    thompson_discrete,
)
from localpbo_core.optimizers.base import Ask, Candidate, Duel, DuelAnswer, Outcome
from localpbo_core.optimizers.gp_acquisition import GPAcquisitionOptimizer, GPAcquisitionOptions
from localpbo_core.optimizers.preference_optimizer import step_generator
from localpbo_core.optimizers.trust_region import (
    TREvent,
    TRStep,
    TrustRegionState,
    perturbed_candidates,
    trust_region_bounds,
)
from localpbo_core.validation import SettingError, check_choice, check_int

ACQUISITIONS = ("ts", "ts_discrete", "qeubo", "ei")


class TuRPBOOptions(GPAcquisitionOptions, total=False):
    """The options of :class:`TuRPBO` (see its Args)."""

    acquisition: str
    num_features: int
    num_mc_samples: int


class TuRPBO(GPAcquisitionOptimizer):
    """Trust-region preferential BO (App. C.5) behind the ask/tell contract.

    Args:
        dim, seed, budget, initial_design, warm_start, hyperparameter_refit_every,
            hyperparameters: see ``GPAcquisitionOptimizer``.
        batch_size: q >= 1 candidates per iteration (TuRPBO table: 1).
        acquisition: ``"ts"`` (Thompson sampling, default: each sample path maximised by
            L-BFGS-B from its best raw candidates), ``"ts_discrete"`` (Thompson sampling on
            the raw candidates only, TuRBO's own scheme: the refinement moves every
            coordinate, and in high dimension it ends on the box's faces), ``"qeubo"`` or
            ``"ei"`` (expected improvement over the incumbent's posterior mean; q = 1 only).
        num_raw_samples: raw candidates in the box (table: 1024).
        num_restarts: L-BFGS-B restarts (table: 5).
        num_features: random features per pathwise sample path.
        num_mc_samples: fixed base samples for qEUBO with q > 1.
    """

    name = "turpbo"

    def __init__(
        self,
        dim: int,
        seed: int,
        budget: int,
        acquisition: str = "ts",
        num_features: int = 1024,
        num_mc_samples: int = 512,
        **options: Unpack[GPAcquisitionOptions],
    ) -> None:
        super().__init__(dim, seed, budget, **options)
        self.acquisition = check_choice("acquisition", acquisition, ACQUISITIONS)
        self.num_features = check_int("num_features", num_features)
        self.num_mc_samples = check_int("num_mc_samples", num_mc_samples)
        if self.acquisition == "ei" and self.batch_size > 1:
            raise SettingError("batch_size", "acquisition 'ei' has no batch form; use 1")
        self.tr = TrustRegionState(dim=self.dim, batch_size=self.batch_size)
        self._center_id: int | None = None
        self._center_challenged = True  # center known to be the global incumbent
        self._restart_pending = False
        self._challenge_duel: Duel | None = None
        self.region_history: list[TRStep] = []

    # ------------------------------------------------------------------ state
    @property
    def center(self) -> Candidate | None:
        """Center of the current trust region (the region's incumbent)."""
        if self._center_id is None:
            return self.incumbent
        return self._candidates[self._center_id]

    @property
    def events(self) -> list[TREvent]:
        """What each iteration's update did to the region (:attr:`region_history`'s events)."""
        return [step.event for step in self.region_history]

    # ------------------------------------------------------------------ ask / tell hooks
    def _propose(self, remaining: int) -> Ask:
        if self._center_id is None:
            self._center_id = self._require_incumbent()
        inc = self._require_incumbent()
        rng = step_generator(self.seed, self._step)
        if self._restart_pending:
            new = self._register([rng.random(self.dim)])
            self._challenge_duel = None
            return Ask(tuple(new), (Duel(new[0].id, inc),))
        q = min(self.batch_size, remaining)
        thetas = self._select(q, rng)
        new = self._register(list(thetas))
        duels = [Duel(c.id, self._center_id) for c in new]
        self._challenge_duel = None
        if self._center_id != inc and not self._center_challenged:
            self._challenge_duel = Duel(self._center_id, inc)
            duels.append(self._challenge_duel)
        return Ask(tuple(new), tuple(duels))

    def _select(self, q: int, rng: np.random.Generator) -> np.ndarray:
        """Candidates in the trust region (App. C.5, Alg. TurPBO lines 4-6)."""
        surrogate = self._fit()
        assert self._center_id is not None  # set by _propose before selecting
        center = self._candidates[self._center_id].theta
        ls = surrogate.lengthscale.detach().numpy()
        lb, ub = trust_region_bounds(center, ls.reshape(-1), self.tr.length)
        raw = perturbed_candidates(center, lb, ub, self.num_raw_samples, rng)
        gen = torch.Generator().manual_seed(int(rng.integers(0, 2**62)))
        if self.acquisition in ("ts", "ts_discrete"):
            path = surrogate.sample_paths(q, gen, num_features=self.num_features)
            if self.acquisition == "ts_discrete":
                return thompson_discrete(path, raw)
            return thompson_batch(path, raw, lb, ub, num_restarts=self.num_restarts)
        if self.acquisition == "ei":
            inc = torch.tensor(self._candidates[self._require_incumbent()].theta)
            with torch.no_grad():
                best = float(surrogate.mean(inc.to(torch.float64)))

            def mean_var(x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
                m, c = surrogate.posterior_mean_cov(x)
                return m, torch.diagonal(c)

            return ei_batch(mean_var, best, raw, lb, ub, num_restarts=self.num_restarts)
        base = torch.randn(self.num_mc_samples, q + 1, generator=gen, dtype=torch.float64)
        return eubo_batch(
            surrogate.posterior_mean_cov,
            center,
            raw,
            lb,
            ub,
            q,
            base,
            rng,
            num_restarts=self.num_restarts,
        )

    def _on_step_complete(
        self, candidates: tuple[Candidate, ...], outcomes: tuple[DuelAnswer, ...]
    ) -> None:
        inc = self._require_incumbent()
        if self._restart_pending:
            # The fresh point: global king-of-the-hill update; it centers the new region.
            self._update_king(outcomes)
            self._restart_pending = False
            self._center_id = candidates[0].id
            self._center_challenged = True
            return
        center = self._center_id
        if self._challenge_duel is not None:
            for o in outcomes:
                pair = {o.winner, o.loser} if isinstance(o, Outcome) else {o.first, o.second}
                if pair == {self._challenge_duel.first, inc}:
                    # a "can't tell" answer keeps the global incumbent
                    if isinstance(o, Outcome) and o.winner == center:
                        self._set_incumbent(o.winner)
                    self._center_challenged = True
            self._challenge_duel = None
        new_ids = {c.id for c in candidates}
        # a "can't tell" answer against the center is no success (it counts as a failure)
        winners = sorted(
            o.winner
            for o in outcomes
            if isinstance(o, Outcome) and o.winner in new_ids and o.loser == center
        )
        success = bool(winners)
        if success:
            was_king = center == self._incumbent_id
            self._center_id = winners[0]
            if was_king:
                self._set_incumbent(winners[0])
            self._center_challenged = was_king
        length = self.tr.length
        event = self.tr.update(success)
        self.region_history.append(TRStep(length, success, event))
        if event is TREvent.RESTART:
            self._restart_pending = True
