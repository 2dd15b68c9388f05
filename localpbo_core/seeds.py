"""Every seed a run derives from its run seed, in one place.

Each derived seed is ``SeedSequence([run seed, TAG, id]).generate_state(1)[0]``:

* the episode seed of candidate ``k`` (``EPISODE_TAG``): the randomness of its one
  evaluation (e.g. MuJoCo's reset noise), so a candidate's value does not depend on which
  process evaluates it, in which order, or how often it is re-published;
* the oracle seed of duel ``k`` (``ORACLE_TAG``): the noise of its comparison (paper
  Sec. 2, eq. (2)), so the answer to a duel is a function of the run seed, the duel id and
  the two values only, on every path (in-process, one ROS process, separate processes,
  resumed runs).

The optimizer's own randomness (initial design, per-step generators) is derived from the same
run seed inside :mod:`localpbo_core.optimizers`.
"""

from __future__ import annotations

import numpy as np

EPISODE_TAG = 0xE915
"""Tag of episode seeds: ``SeedSequence([run_seed, EPISODE_TAG, candidate_id])``."""

ORACLE_TAG = 0x0AC1
"""Tag of per-duel oracle seeds: ``SeedSequence([run_seed, ORACLE_TAG, duel_id])``."""


def _derive(run_seed: int, tag: int, key: int) -> int:
    ss = np.random.SeedSequence([int(run_seed), tag, int(key)])
    return int(ss.generate_state(1, dtype=np.uint32)[0])


def episode_seed(run_seed: int, candidate_id: int) -> int:
    """The seed of candidate ``candidate_id``'s evaluation."""
    return _derive(run_seed, EPISODE_TAG, candidate_id)


def duel_seed(run_seed: int, duel_id: int) -> int:
    """The seed of the oracle noise of duel ``duel_id``."""
    return _derive(run_seed, ORACLE_TAG, duel_id)
