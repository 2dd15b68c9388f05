"""Synthetic benchmark functions of the paper (Sec. 6, App. D.5), negated to maximisation.

Each function is the BoTorch 0.18.1 test function of the same name (a minimisation problem on
its native box), re-implemented in numpy (no torch at evaluation time; equality with BoTorch
is tested in ``tests/problems/test_problems_synthetic.py``), negated so that problems are maximised,
and composed with the affine map of [0,1]^d onto the native box (paper App. D.1, "Input
normalization"): ``x = lower + (upper - lower) * theta``.

``value_range``: max − min of the (negated) function over the first 10,000 points of a
scrambled Sobol sequence, ``scipy.stats.qmc.Sobol(d, scramble=True, seed=0)``, computed
offline by ``python -m localpbo_core.problems.calibrate --problem NAME --points 10000``; the
oracle's noise std is a fraction of it (paper Sec. 6: "10% of the approximated function
value range", eq. (2) "observation noise").
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from localpbo_core.validation import SettingError, check_int, check_theta

_HARTMANN6_ALPHA = np.array([1.0, 1.2, 3.0, 3.2])
_HARTMANN6_A = np.array(
    [
        [10, 3, 17, 3.5, 1.7, 8],
        [0.05, 10, 17, 0.1, 8, 14],
        [3, 3.5, 1.7, 10, 17, 8],
        [17, 8, 0.05, 10, 0.1, 14],
    ]
)
_HARTMANN6_P = 1e-4 * np.array(
    [
        [1312, 1696, 5569, 124, 8283, 5886],
        [2329, 4135, 8307, 3736, 1004, 9991],
        [2348, 1451, 3522, 2883, 3047, 6650],
        [4047, 8828, 8732, 5743, 1091, 381.0],
    ]
)


def hartmann6(x: np.ndarray) -> np.ndarray:
    """Hartmann 6 (minimisation): ``-sum_i alpha_i exp(-sum_j A_ij (x_j - P_ij)^2)``."""
    inner = np.sum(_HARTMANN6_A * (x[..., None, :] - _HARTMANN6_P) ** 2, axis=-1)
    return -np.sum(_HARTMANN6_ALPHA * np.exp(-inner), axis=-1)


def rosenbrock(x: np.ndarray) -> np.ndarray:
    """Rosenbrock (minimisation): ``sum_i 100 (x_{i+1} - x_i^2)^2 + (x_i - 1)^2``."""
    return np.sum(100.0 * (x[..., 1:] - x[..., :-1] ** 2) ** 2 + (x[..., :-1] - 1.0) ** 2, axis=-1)


def levy(x: np.ndarray) -> np.ndarray:
    """Levy (minimisation) with ``w = 1 + (x - 1) / 4`` (BoTorch's definition)."""
    w = 1.0 + (x - 1.0) / 4.0
    part1 = np.sin(np.pi * w[..., 0]) ** 2
    part2 = np.sum(
        (w[..., :-1] - 1.0) ** 2 * (1.0 + 10.0 * np.sin(np.pi * w[..., :-1] + 1.0) ** 2), axis=-1
    )
    part3 = (w[..., -1] - 1.0) ** 2 * (1.0 + np.sin(2.0 * np.pi * w[..., -1]) ** 2)
    return part1 + part2 + part3


def styblinski_tang(x: np.ndarray) -> np.ndarray:
    """Styblinski–Tang (minimisation): ``0.5 * sum_i (x_i^4 - 16 x_i^2 + 5 x_i)``."""
    return 0.5 * np.sum(x**4 - 16.0 * x**2 + 5.0 * x, axis=-1)


@dataclass(frozen=True)
class SyntheticProblem:
    """A negated BoTorch test function on [0,1]^d (deterministic: ``evaluate == true_value``).

    Attributes:
        name: registry name.
        dim: d.
        lower, upper: native box (same bound in every coordinate).
        minimise_fn: the BoTorch-form (minimisation) function on native inputs.
        value_range: max − min over 10,000 scrambled Sobol points (module docstring).
        optimal_value: the known maximum of the negated function.
        optimizer_native: a known maximiser in native units.
    """

    name: str
    dim: int
    lower: float
    upper: float
    minimise_fn: Callable[[np.ndarray], np.ndarray]
    value_range: float
    optimal_value: float
    optimizer_native: tuple[float, ...]

    def to_native(self, theta: np.ndarray) -> np.ndarray:
        """``lower + (upper - lower) * theta``."""
        arr = check_theta("theta", theta, self.dim)
        return self.lower + (self.upper - self.lower) * arr

    def from_native(self, x: np.ndarray) -> np.ndarray:
        """Inverse of ``to_native`` (no clipping; x must lie in the box)."""
        return (np.asarray(x, dtype=np.float64) - self.lower) / (self.upper - self.lower)

    @property
    def optimizer(self) -> np.ndarray:
        """A known maximiser in [0,1]^d."""
        return self.from_native(np.asarray(self.optimizer_native))

    def values(self, thetas: np.ndarray) -> np.ndarray:
        """Vectorised negated values for an (n, d) array of thetas in [0,1]^d."""
        arr = np.asarray(thetas, dtype=np.float64)
        if arr.ndim != 2 or arr.shape[1] != self.dim:
            raise SettingError("thetas", f"expected shape (n, {self.dim}), got {arr.shape}")
        if not np.all(np.isfinite(arr)):
            raise SettingError("thetas", "contains NaN or inf")
        if np.any(arr < 0.0) or np.any(arr > 1.0):
            raise SettingError("thetas", f"must lie in [0, 1]^{self.dim}")
        return -self.minimise_fn(self.lower + (self.upper - self.lower) * arr)

    def true_value(self, theta: np.ndarray) -> float:
        """Negated function value at theta (noise-free)."""
        return float(-self.minimise_fn(self.to_native(theta)))

    def evaluate(self, theta: np.ndarray, seed: int) -> float:
        """Same as ``true_value`` (the function is deterministic; ``seed`` is only checked)."""
        check_int("seed", seed, minimum=0)
        return self.true_value(theta)

    def evaluate_native(self, x: np.ndarray, seed: int) -> float:
        """Negated function value at native ``x`` (inside the box ``[lower, upper]^d``)."""
        check_int("seed", seed, minimum=0)
        arr = np.asarray(x, dtype=np.float64)
        if arr.shape != (self.dim,):
            raise SettingError("x", f"expected shape ({self.dim},), got {arr.shape}")
        if not np.all(np.isfinite(arr)) or np.any(arr < self.lower) or np.any(arr > self.upper):
            raise SettingError("x", f"must be finite and lie in [{self.lower}, {self.upper}]^d")
        return float(-self.minimise_fn(arr))


# max − min over 10,000 scrambled Sobol points (seed 0); reproduce with
# `python -m localpbo_core.problems.calibrate --problem NAME --points 10000`.
SYNTHETIC_VALUE_RANGES: dict[str, float] = {
    "hartmann6": 3.0100713839207427,
    "rosenbrock16": 5301422.7366539175,
    "levy32": 655.1910623286794,
    "styblinskitang32": 1424.4448978762982,
    "styblinskitang64": 1806.4243389462445,
}

_ST_ARGMIN = -2.903534


def make_synthetic(name: str) -> SyntheticProblem:
    """Create one of ``SYNTHETIC_PROBLEMS`` by name."""
    if name == "hartmann6":
        opt = (0.20169, 0.150011, 0.476874, 0.275332, 0.311652, 0.6573)
        return SyntheticProblem(
            name, 6, 0.0, 1.0, hartmann6, SYNTHETIC_VALUE_RANGES[name], 3.32237, opt
        )
    if name == "rosenbrock16":
        return SyntheticProblem(
            name, 16, -5.0, 10.0, rosenbrock, SYNTHETIC_VALUE_RANGES[name], 0.0, (1.0,) * 16
        )
    if name == "levy32":
        return SyntheticProblem(
            name, 32, -10.0, 10.0, levy, SYNTHETIC_VALUE_RANGES[name], 0.0, (1.0,) * 32
        )
    if name in ("styblinskitang32", "styblinskitang64"):
        dim = int(name.removeprefix("styblinskitang"))
        return SyntheticProblem(
            name,
            dim,
            -5.0,
            5.0,
            styblinski_tang,
            SYNTHETIC_VALUE_RANGES[name],
            39.166166 * dim,
            (_ST_ARGMIN,) * dim,
        )
    raise ValueError(f"name: unknown synthetic problem {name!r}; valid: {SYNTHETIC_PROBLEMS}")


SYNTHETIC_PROBLEMS: tuple[str, ...] = (
    "hartmann6",
    "levy32",
    "rosenbrock16",
    "styblinskitang32",
    "styblinskitang64",
)
