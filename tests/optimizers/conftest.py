"""Fixtures for optimizer tests (helpers live in ``optim_helpers.py``)."""

from __future__ import annotations

from collections.abc import Iterator

import pytest
import torch
from optim_helpers import FakeSurrogate


@pytest.fixture
def one_torch_thread() -> Iterator[None]:
    """Run the test single-threaded in torch (restored afterwards)."""
    previous = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(previous)


@pytest.fixture
def fake_fit(monkeypatch: pytest.MonkeyPatch) -> None:
    """Replace TuRPBO's surrogate fit by :class:`FakeSurrogate` (state-machine tests)."""
    from localpbo_core.optimizers.turpbo import TuRPBO

    def _fit(self: TuRPBO) -> FakeSurrogate:
        self._surrogate = FakeSurrogate(torch.tensor(self.train_inputs()))
        return self._surrogate

    monkeypatch.setattr(TuRPBO, "_fit", _fit)
