"""HB-EI baseline: hallucination believer with expected improvement (paper Sec. 6 baselines,
App. D/E; Takeno et al. 2023, the method "HB-EI").

Takeno, Nomura and Karasuyama (2023, ICML, "Towards practical preferential Bayesian
optimization with skew Gaussian processes") observe that the exact posterior of a GP under the
probit duel likelihood is a skew GP, and that one posterior draw of the noisy utility
differences ``g`` (a "hallucination") turns it into an ordinary GP. Each iteration here:

1. Hyperparameters (see below) give the kernel; the Markov chain of
   :class:`~localpbo_core.surrogate.skew_gp.DuelPosteriorChain` (linear elliptical slice
   sampling, exact skew-GP posterior, warm-started from the previous iteration's state) is
   moved to the posterior of all duels so far, and its state ``g`` is the hallucination.
2. The GP of the latent utility given ``g`` (same kernel; ``mu_g``, ``var_g`` of
   :mod:`~localpbo_core.surrogate.skew_gp`) is the "believed" model. As in Takeno et al.'s
   implementation the GP is conditioned on the hallucinated noisy differences ``g`` (GP
   regression with observation matrix ``H`` and noise variance ``2 sigma^2``), not on a draw
   of ``f`` at the points, so EI keeps the uncertainty of ``f`` given ``g``.
3. The next point maximises expected improvement over the believed GP against the
   hallucinated value of the current winner, ``f* = mu_g(x_inc)`` (Takeno et al.: the "current
   best" is the winner of the last duel, i.e. the king of the hill):
   ``EI(x) = (mu_g(x) - f*) Phi(z) + s_g(x) phi(z)``, ``z = (mu_g(x) - f*) / s_g(x)``.
4. It is dueled against the current winner; the winner becomes the incumbent (king of the
   hill, App. D.1). Batch size 1.

Hyperparameters, as Takeno et al. do (their ``PreferentialGP_Laplace.model_selection`` and
experiment script): the kernel variance and the preference noise are *fixed* (variance 1,
noise std 0.01), and the ARD lengthscales are learned by maximising the *Laplace-approximated*
marginal likelihood of the pairwise GP (Chu & Ghahramani), not on the hallucination, at the
start and after every 10 duels, held in between. Here the Laplace fit is this package's
surrogate (paper Sec. 4), so the units are its probit noise sigma = 1: the fixed
signal-to-noise ratio of Takeno et al. becomes ``outputscale = (1 / 0.01)^2 = 1e4``
(:data:`TAKENO_OUTPUTSCALE`); the lengthscales keep the shared settings of App. D.2 (prior
Gamma(2.4, 2.7) within [0.05, 0.5]; Takeno et al.: no prior, within [0.1, 0.5]), warm-started
from the previous fit. ``outputscale=None`` learns the outputscale too (the shared
SmoothedBoxPrior(0.01, 100) setting of the other pairwise-GP methods). Under the benchmarks'
10 % oracle noise that fit stays near its lower bound for many iterations (Hartmann 6, seed 0:
outputscale 0.01-0.02 for the first 40 duels; early duels look like coin flips) and the
believed GP is then almost flat; measured mean best value on Hartmann 6 over seeds 0-2:
2.03 learned, 2.91 fixed (optimum 3.32).
``hyperparameter_refit_every=1`` relearns every iteration.

**Fixed hyperparameters** (the paper's within-model runs, App. D.4): the ``hyperparameters``
option of the other model-based algorithms (:func:`~localpbo_core.optimizers.surrogate_refit.
check_hyperparameters`), e.g. ``{"lengthscale": 0.1, "outputscale": 2.0}``. A given lengthscale
is never learned and a given outputscale replaces ``outputscale``; when both are given nothing
is learned, the kernel never changes, and the chain is never restarted after its first burn-in.

Sampler schedule: a chain started afresh, or continued after new hyperparameters, takes
``burn_in`` LinESS steps; otherwise (one duel appended, same kernel: the Cholesky factor of
``M`` is extended by one row) ``steps_per_iteration`` steps. With Takeno et al.'s confident
kernel the posterior of ``g`` is much narrower than its prior ``N(0, M)`` and LinESS mixes
slowly: integrated autocorrelation times of 400-2600 steps for coordinates of ``g`` and
about 850-1450 steps for the hallucinated utility at the best point, measured at the end of
Hartmann 6 and Rosenbrock 16 runs (seed 0). The defaults (5000 and 1000 steps) therefore give
about one effective independent hallucination per iteration; a step costs ``O(m^2)`` (one
matrix-vector product with ``L_M``, drawn in blocks), ~0.03-0.07 ms at ``m`` = 60-160 duels.
Takeno et al. instead run a fresh Gibbs chain with 1000 burn-in sweeps every iteration.

EI maximisation: ``num_raw_samples`` uniform points of [0,1]^d plus the incumbent, the best
``num_restarts`` of them polished by one batched L-BFGS-B run on closed-form gradients (the
1024 raw samples / 5 restarts of the other acquisition optimisers; Takeno et al. use 20 d Sobol
starts plus the current best). Every random draw (chain, raw samples) comes from
``step_generator(seed, step)``, so the same seed and outcomes give bit-identical candidates.
"Can't tell" answers (``tie_threshold`` ``eps > 0``): the skew-GP posterior becomes the normal
restricted to ``g_k >= eps`` for decisive duels and ``|g_k| < eps`` for ties (the ordinal
likelihood of :mod:`localpbo_core.surrogate.ordinal`, sampled as in
:mod:`localpbo_core.surrogate.skew_gp`); a tie keeps the current winner.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Unpack

import numpy as np
import torch
from scipy.special import ndtr

from localpbo_core.optimizers.acquisition import _lbfgsb_multistart
from localpbo_core.optimizers.preference_optimizer import (
    KingOfTheHillOptimizer,
    RunOptions,
    check_multistart,
    check_one_per_ask,
    step_generator,
)
from localpbo_core.optimizers.surrogate_refit import check_hyperparameters
from localpbo_core.surrogate import PairwiseGPSurrogate, Surrogate
from localpbo_core.surrogate.skew_gp import ConditionedGP, DuelPosteriorChain
from localpbo_core.validation import check_float, check_int

_INV_SQRT_2PI = 1.0 / np.sqrt(2.0 * np.pi)
#: Takeno et al.'s fixed kernel variance 1 and preference noise std 0.01, in the units of this
#: package (noise std 1): outputscale = (1 / 0.01)^2.
TAKENO_OUTPUTSCALE = 1.0e4


def expected_improvement(
    gp: ConditionedGP, best: float, x: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """EI ``(N,)`` of the believed GP against ``best`` at ``x`` ``(N, d)`` and its gradient
    ``(N, d)``: ``dEI = Phi(z) dmu + phi(z) ds``, ``ds = dvar / (2 s)``."""
    mu, var, dmu, dvar = gp.mean_var_grad(x)
    s = np.sqrt(var)
    z = (mu - best) / s
    cdf = ndtr(z)
    pdf = _INV_SQRT_2PI * np.exp(-0.5 * z * z)
    ei = (mu - best) * cdf + s * pdf
    grad = cdf[:, None] * dmu + (pdf / (2.0 * s))[:, None] * dvar
    return ei, grad


def expected_improvement_value(gp: ConditionedGP, best: float, x: np.ndarray) -> np.ndarray:
    """EI ``(N,)`` of :func:`expected_improvement` without the gradient."""
    mu, var = gp.mean_var(x)
    s = np.sqrt(var)
    z = (mu - best) / s
    return (mu - best) * ndtr(z) + s * _INV_SQRT_2PI * np.exp(-0.5 * z * z)


class HBEI(KingOfTheHillOptimizer):
    """HB-EI (Takeno et al. 2023) behind the ask/tell contract; see the module docstring.

    Args:
        dim, seed, budget, initial_design, warm_start: see ``PreferenceOptimizer``.
        batch_size: must be 1 (one new point per iteration, dueled against the winner).
        num_raw_samples: uniform raw points for the EI maximisation (1024).
        num_restarts: L-BFGS-B starts, the best raw points (5).
        burn_in: LinESS steps for a fresh chain or after new hyperparameters (5000).
        steps_per_iteration: LinESS steps per iteration otherwise (1000).
        hyperparameter_refit_every: k >= 1; learn the hyperparameters on the Laplace evidence
            at iterations 0, k, 2k, ... (Takeno et al.: 10) and hold them in between.
        outputscale: the fixed kernel variance ``s`` (default Takeno et al.'s 1e4 in these
            units, see above), or None to learn it with the lengthscales.
        hyperparameters: fixed lengthscale and/or outputscale (see above); None: as above.
    """

    name = "hbei"

    def __init__(
        self,
        dim: int,
        seed: int,
        budget: int,
        batch_size: int = 1,
        num_raw_samples: int = 1024,
        num_restarts: int = 5,
        burn_in: int = 5000,
        steps_per_iteration: int = 1000,
        hyperparameter_refit_every: int = 10,
        outputscale: float | None = TAKENO_OUTPUTSCALE,
        hyperparameters: Mapping[str, object] | None = None,
        **run: Unpack[RunOptions],
    ) -> None:
        check_one_per_ask(batch_size, "HB-EI proposes one point per iteration")
        super().__init__(dim, seed, budget, batch_size=1, **run)
        self.num_restarts, self.num_raw_samples = check_multistart(
            num_restarts, num_raw_samples, spare=1
        )
        self.burn_in = check_int("burn_in", burn_in, minimum=0)
        self.steps_per_iteration = check_int("steps_per_iteration", steps_per_iteration, 0)
        self.hyperparameter_refit_every = check_int(
            "hyperparameter_refit_every", hyperparameter_refit_every
        )
        self.outputscale = (
            None
            if outputscale is None
            else check_float("outputscale", outputscale, minimum=0.0, minimum_open=True)
        )
        fixed = check_hyperparameters(hyperparameters, self.dim)
        self._fixed_lengthscale: torch.Tensor | None = None
        if fixed is not None and fixed.lengthscale is not None:
            self._fixed_lengthscale = torch.tensor(fixed.lengthscale, dtype=torch.float64)
        if fixed is not None and fixed.outputscale is not None:
            self.outputscale = fixed.outputscale
        self.chain = DuelPosteriorChain(tie_threshold=self.tie_threshold)
        self._laplace: PairwiseGPSurrogate | None = None
        self._iterations = 0
        #: The believed GP of the last iteration (for inspection).
        self.believed: ConditionedGP | None = None

    @property
    def surrogate(self) -> Surrogate | None:
        """The last Laplace fit, the one that learned the current hyperparameters."""
        return self._laplace

    def _hyperparameters(self) -> tuple[np.ndarray, float, bool]:
        """Lengthscales, outputscale and whether they were relearned this iteration."""
        relearn = self._laplace is None or self._iterations % self.hyperparameter_refit_every == 0
        if relearn:
            self._laplace = PairwiseGPSurrogate.fit(
                torch.tensor(self.train_inputs(), dtype=torch.float64),
                torch.tensor(self.comparisons(), dtype=torch.long),
                lengthscale=self._fixed_lengthscale,
                outputscale=self.outputscale,
                warm_start=self._laplace,
                ties=torch.tensor(self.ties(), dtype=torch.long),
                tie_threshold=self.tie_threshold,
            )
        assert self._laplace is not None
        learned = self._fixed_lengthscale is None or self.outputscale is None
        return (
            self._laplace.lengthscale.numpy().copy(),
            float(self._laplace.outputscale),
            relearn and learned,
        )

    def _propose_thetas(self, q: int) -> list[np.ndarray]:
        rng = step_generator(self.seed, self._step)
        ls, s, relearned = self._hyperparameters()
        rows, tie = self.duel_rows()  # in tell order, so the chain's state stays a prefix
        kept = self.chain.update(
            self.train_inputs(), rows[:, 0], rows[:, 1], ls, s, rng, tie if tie.any() else None
        )
        steps = self.steps_per_iteration if kept and not relearned else self.burn_in
        self.chain.run(steps, rng)
        gp = self.chain.conditioned_gp()
        self.believed = gp
        inc = self._candidates[self._require_incumbent()].theta
        best = float(gp.mean_var(inc[None, :])[0][0])

        raw = np.vstack([inc[None, :], rng.random((self.num_raw_samples, self.dim))])
        vals = expected_improvement_value(gp, best, raw)
        starts = raw[np.argsort(-vals, kind="stable")[: self.num_restarts]]

        def value_and_grad(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            return expected_improvement(gp, best, x)

        def values(x: np.ndarray) -> np.ndarray:
            return expected_improvement_value(gp, best, x)

        lo, hi = np.zeros(self.dim), np.ones(self.dim)
        xs, fs = _lbfgsb_multistart(value_and_grad, values, starts, lo, hi, maxiter=200)
        self._iterations += 1
        return [xs[int(np.argmax(fs))]]
