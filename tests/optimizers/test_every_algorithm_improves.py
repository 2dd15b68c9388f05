"""Across the registry: every algorithm improves on a smooth 2-D and 6-D
problem under noise-free preferences, with the paper's budget 2 + 10 d (App. D.1)."""

from __future__ import annotations

import numpy as np
import pytest
from optim_helpers import drive, utility

from localpbo_core.optimizers import available_optimizers, make_optimizer


@pytest.mark.parametrize("dim", [2, 6])
@pytest.mark.parametrize("name", [a for a in available_optimizers() if a != "sobol"])
def test_improves_on_smooth_problem_without_noise(name: str, dim: int) -> None:
    opt = make_optimizer(name, dim, seed=1, budget=2 + 10 * dim)
    thetas = drive(opt)
    values = np.array([utility(t) for t in thetas])
    initial_best = values[:2].max()
    # the best evaluated point closes at least half of the gap to the optimum (0 at 0.3)
    assert values.max() >= 0.5 * initial_best, (name, dim, initial_best, values.max())
    # and the preference-defined incumbent is better than the initial one
    assert utility(opt.incumbent.theta) > initial_best
