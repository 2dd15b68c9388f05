"""Fixtures of the surrogate tests (helpers live in surrogate_helpers.py)."""

from __future__ import annotations

import pytest
import torch
from surrogate_helpers import loop_duels


@pytest.fixture(autouse=True)
def _one_torch_thread():
    """Run each surrogate test single-threaded (restored afterwards): on the shared 2-core box
    torch's thread pool stalls badly on these small matrices when other processes run."""
    previous = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(previous)


@pytest.fixture
def duels():
    return loop_duels
