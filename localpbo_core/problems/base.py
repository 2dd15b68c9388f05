"""The problem contract shared by synthetic functions and MuJoCo policy tasks.

Every problem is *maximised* on the unit cube [0,1]^d (paper App. D.1, "Input
normalization"): algorithms only ever see theta in [0,1]^d and duel outcomes; the
problem maps theta to its native units and produces the values the oracle compares.

``Problem`` is a structural protocol so that ``localpbo_sims`` (MuJoCo tasks) satisfies it
without importing ``localpbo_core``.
"""

from __future__ import annotations

from typing import Protocol, runtime_checkable

import numpy as np


@runtime_checkable
class Problem(Protocol):
    """A maximisation problem on [0,1]^d (read-only attributes: frozen dataclasses and plain
    classes both satisfy it)."""

    @property
    def name(self) -> str:
        """Registry name, e.g. ``"hartmann6"`` or ``"hopper"``."""
        ...

    @property
    def dim(self) -> int:
        """Dimension d of theta."""
        ...

    @property
    def value_range(self) -> float:
        """The approximate function-value range used to scale the oracle noise (paper Sec. 6:
        noise std = 10% of the approximate value range)."""
        ...

    def to_native(self, theta: np.ndarray) -> np.ndarray:
        """Map theta in [0,1]^d to the problem's own units (e.g. policy weights)."""
        ...

    def evaluate(self, theta: np.ndarray, seed: int) -> float:
        """One evaluation (e.g. one episode) of theta; ``seed`` fixes its randomness.

        This is the value a real experiment would produce; the oracle adds its own
        comparison noise on top (paper eq. (2) "observation noise").
        """
        ...

    def evaluate_native(self, x: np.ndarray, seed: int) -> float:
        """One evaluation of parameters ``x`` given in the problem's own units.

        ``evaluate(theta, seed) == evaluate_native(to_native(theta), seed)``: a simulator or
        controller that receives native parameters evaluates exactly what the optimizer
        proposed (no round trip through [0,1]^d). ``x`` must lie in the box.
        """
        ...

    def true_value(self, theta: np.ndarray) -> float:
        """The noise-free value of theta used for reporting (best-seen, cumulative).

        Algorithms never see it. For deterministic problems this equals ``evaluate``.
        """
        ...
