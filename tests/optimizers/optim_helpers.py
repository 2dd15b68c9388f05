"""Shared helpers for optimizer tests: a tiny problem and a fake surrogate.

The fake surrogate stands in for ``PairwiseGPSurrogate`` only where a test checks the
TuRPBO *state machine* (counters, restarts, duels), which must not depend on GP details.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping

import numpy as np
import torch
from torch import Tensor

from localpbo_core.optimizers import Duel, Outcome, PreferenceOptimizer


class FakeSurrogate:
    """Deterministic stand-in with the surrogate API used by TuRPBO."""

    def __init__(self, X: Tensor) -> None:
        self.train_inputs = X
        self.lengthscale = torch.full((X.shape[1],), 0.2, dtype=torch.float64)

    def sample_paths(
        self, num_paths: int, generator: torch.Generator, num_features: int = 1024
    ) -> Callable[[Tensor], Tensor]:
        d = self.train_inputs.shape[1]
        c = torch.rand(num_paths, d, generator=generator, dtype=torch.float64)

        def path(x: Tensor) -> Tensor:
            return -((x[:, None, :] - c[None, :, :]) ** 2).sum(-1)

        return path

    def posterior_mean_cov(self, Xq: Tensor) -> tuple[Tensor, Tensor]:
        mean = -((Xq - 0.3) ** 2).sum(-1)
        cov = torch.exp(-0.5 * torch.cdist(Xq, Xq) ** 2 / 0.04) + 1e-6 * torch.eye(Xq.shape[0])
        return mean, cov


def utility(theta: np.ndarray) -> float:
    """A smooth test utility on [0,1]^d with maximum at 0.3."""
    return float(-np.sum((np.asarray(theta) - 0.3) ** 2))


def judged(values: Mapping[int, float], duels: Iterable[Duel]) -> list[Outcome]:
    """Noise-free outcomes of ``duels`` by ``values`` (candidate id -> value): the higher value
    wins, the first side on a tie."""
    return [
        Outcome(d.first, d.second)
        if values[d.first] >= values[d.second]
        else Outcome(d.second, d.first)
        for d in duels
    ]


def drive(
    opt: PreferenceOptimizer,
    judge: Callable[[np.ndarray], float] = utility,
    noise: float = 0.0,
    rng: np.random.Generator | None = None,
) -> list[np.ndarray]:
    """Run ``opt`` to the end with duels on ``judge``, each side's value plus ``noise`` times a
    standard normal draw of ``rng`` (first side first; noise-free by default); return all
    thetas."""
    values: dict[int, float] = {}
    while not opt.done:
        ask = opt.ask()
        for c in ask.candidates:
            values[c.id] = judge(c.theta)
        outs = []
        for d in ask.duels:
            a, b = d.first, d.second
            va, vb = values[a], values[b]
            if noise:
                assert rng is not None
                va += noise * rng.standard_normal()
                vb += noise * rng.standard_normal()
            outs.append(Outcome(a, b) if va >= vb else Outcome(b, a))
        opt.tell(outs)
    return [c.theta for c in opt.history.candidates]
