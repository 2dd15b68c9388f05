"""ARS reference linear policies and observation statistics (data in ``data/ars/``).

Two trained linear policies from the public ARS repository (Mania et al. 2018, "Simple random
search provides a competitive approach to reinforcement learning", cited by the paper in
Sec. 6 "Policy Search" and App. D.6 "Policy-Search"). Each file holds ``W`` (actions x
obs), the observation mean and the observation std; the policy is
``a = W @ ((obs - mean) / std)`` (ARS "V2").
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

DATA_DIR = Path(__file__).resolve().parent / "data" / "ars"

ARS_FILES: dict[str, str] = {
    "hopper": "hopper_v1_lin_policy_plus.npz",
    "walker2d": "walker2d_v1_gait5_reward_11200.npz",
}


@dataclass(frozen=True)
class ArsPolicy:
    """A trained ARS linear policy: ``a = weights @ ((obs - obs_mean) / obs_std)``."""

    weights: np.ndarray
    obs_mean: np.ndarray
    obs_std: np.ndarray


def load_ars_policy(task: str) -> ArsPolicy:
    """Load the ARS policy and observation statistics for ``task`` ("hopper" or "walker2d")."""
    if task not in ARS_FILES:
        raise ValueError(f"task: no ARS data for {task!r}; valid: {sorted(ARS_FILES)}")
    arrays = np.load(DATA_DIR / ARS_FILES[task], allow_pickle=True)["arr_0"]
    weights, mean, std = (np.asarray(a, dtype=np.float64) for a in arrays)
    return ArsPolicy(weights=weights, obs_mean=mean, obs_std=std)
