"""GP sample-path problems (paper Sec. 6, App. D.4 "GP sample paths").

A problem is one function drawn from a zero-mean GP with squared-exponential kernel

    k(x, y) = s * exp(-||x - y||^2 / (2 l^2)),   s = 1 (outputscale),

on [0,1]^d, maximised. The paper uses d in {8, 16, 32, 64, 96} and l in {0.1, 0.5}; in its
*within-model* runs the optimizers get the true hyperparameters (``hyperparameters`` below,
converted to the duel likelihood's units, outputscale ``s / sigma_n^2``, by
:func:`localpbo_core.experiments.spec.duel_hyperparameters` and passed to the model-based
algorithms as their ``hyperparameters`` option), in the *out-of-model* runs they learn them.

**How a path is drawn.** Random Fourier features (Rahimi & Recht) with ``F`` features
(default :data:`DEFAULT_FEATURES` = 4096):

    f(x) = sqrt(2 s / F) * sum_f w_f cos(omega_f . x + b_f),
    omega_f ~ N(0, I / l^2),  b_f ~ U(0, 2 pi),  w_f ~ N(0, 1),

all drawn from ``numpy.random.default_rng(SeedSequence([GP_TAG, d, bits(l), instance, F]))``
(``bits(l)`` = the IEEE-754 bits of l), so a problem is fixed by (d, l, instance, F) on every
machine that runs numpy's PCG64. Over the draw of (omega, b, w) the covariance of f is exactly
k for every F; a single path is Gaussian up to the Monte Carlo error of F features in the
kernel (about 1/sqrt(F) per entry). ``tests/problems/test_gp_samples.py`` checks both against
the exact kernel matrix at a few hundred points (empirical covariance over many paths within
Monte Carlo error, and a KS test of the whitened values of single paths).

**Noise scale.** ``value_range`` is defined as for the other problems: max − min of the
function over the first :data:`VALUE_RANGE_POINTS` = 10,000 points of
``scipy.stats.qmc.Sobol(d, scramble=True, seed=0)``; it is computed when the problem is built
on first use (about two seconds at d = 96; the problem is cached per process) rather than
stored, since every
(d, l, instance) is a different function.

The box is [0,1]^d itself: ``to_native`` is the identity and ``evaluate_native(x)`` evaluates
the same expression as ``evaluate(theta)`` (bit-identical), deterministic (``evaluate ==
true_value``; the seed is only checked).
"""

from __future__ import annotations

import functools
import warnings

import numpy as np

from localpbo_core.validation import SettingError, check_float, check_int, check_theta

GP_SAMPLE_PROBLEM = "gp_sample"
"""Registry name; options ``dim``, ``lengthscale``, ``instance``, ``num_features``."""

GP_TAG = 0x6795
"""Tag mixed into the seed of every path (independent of any run seed)."""

DEFAULT_FEATURES = 4096
"""Random Fourier features per path."""

OUTPUTSCALE = 1.0
"""The kernel's outputscale s (paper App. D.4)."""

VALUE_RANGE_POINTS = 10_000
"""Scrambled Sobol points (seed 0) of the value range, as for the synthetic functions."""

_CHUNK = 1024


def _lengthscale_bits(lengthscale: float) -> int:
    return int(np.array(lengthscale, dtype=np.float64).view(np.uint64))


class GPSampleProblem:
    """One GP sample path on [0,1]^d (module docstring).

    Build with :func:`make_gp_sample` (validated, cached per process). Attributes ``omega``
    (F, d), ``phase`` (F,) and ``weights`` (F,) hold the drawn features (``weights`` already
    scaled by ``sqrt(2 s / F)``); ``value_range`` is computed on first use.
    """

    name = GP_SAMPLE_PROBLEM

    def __init__(self, dim: int, lengthscale: float, instance: int, num_features: int) -> None:
        self.dim = dim
        self.lengthscale = lengthscale
        self.instance = instance
        self.num_features = num_features
        self.omega, self.phase, self.weights = draw_features(
            dim, lengthscale, instance, num_features
        )
        for arr in (self.omega, self.phase, self.weights):
            arr.setflags(write=False)

    def __repr__(self) -> str:
        return (
            f"GPSampleProblem(dim={self.dim}, lengthscale={self.lengthscale}, "
            f"instance={self.instance}, num_features={self.num_features})"
        )

    @functools.cached_property
    def value_range(self) -> float:
        """max − min over the first 10,000 scrambled Sobol points (module docstring)."""
        return sobol_value_range(self)

    @property
    def hyperparameters(self) -> dict[str, float]:
        """The true kernel hyperparameters of ``f`` (within-model runs give the optimizers
        these in the duel likelihood's units: module docstring)."""
        return {"lengthscale": self.lengthscale, "outputscale": OUTPUTSCALE}

    def _value(self, x: np.ndarray) -> float:
        return float(np.dot(self.weights, np.cos(self.omega @ x + self.phase)))

    def values(self, thetas: np.ndarray) -> np.ndarray:
        """Vectorised values for an (n, d) array in [0,1]^d (chunked matrix products; equal
        to :meth:`true_value` up to floating-point summation order)."""
        arr = np.asarray(thetas, dtype=np.float64)
        if arr.ndim != 2 or arr.shape[1] != self.dim:
            raise SettingError("thetas", f"expected shape (n, {self.dim}), got {arr.shape}")
        out = np.empty(arr.shape[0])
        for start in range(0, arr.shape[0], _CHUNK):
            block = arr[start : start + _CHUNK]
            out[start : start + _CHUNK] = np.cos(block @ self.omega.T + self.phase) @ self.weights
        return out

    def to_native(self, theta: np.ndarray) -> np.ndarray:
        """The identity (the box is [0,1]^d), as a new array."""
        return np.array(check_theta("theta", theta, self.dim))

    def true_value(self, theta: np.ndarray) -> float:
        """f(theta) (noise-free)."""
        return self._value(check_theta("theta", theta, self.dim))

    def evaluate(self, theta: np.ndarray, seed: int) -> float:
        """Same as ``true_value`` (deterministic; ``seed`` is only checked)."""
        check_int("seed", seed, minimum=0)
        return self.true_value(theta)

    def evaluate_native(self, x: np.ndarray, seed: int) -> float:
        """f(x) for x in [0,1]^d (the native box)."""
        check_int("seed", seed, minimum=0)
        return self._value(check_theta("x", x, self.dim))


def draw_features(
    dim: int, lengthscale: float, instance: int, num_features: int = DEFAULT_FEATURES
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(omega, phase, weights)`` of path ``instance`` (module docstring); weights scaled."""
    seq = np.random.SeedSequence(
        [GP_TAG, dim, _lengthscale_bits(lengthscale), instance, num_features]
    )
    rng = np.random.default_rng(seq)
    omega = rng.standard_normal((num_features, dim)) / lengthscale
    phase = rng.uniform(0.0, 2.0 * np.pi, num_features)
    weights = rng.standard_normal(num_features) * np.sqrt(2.0 * OUTPUTSCALE / num_features)
    return omega, phase, weights


def sobol_value_range(problem: GPSampleProblem, points: int = VALUE_RANGE_POINTS) -> float:
    """max − min of ``problem.values`` over the first ``points`` scrambled Sobol points."""
    from scipy.stats import qmc

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)  # 10,000 is not a power of 2
        pts = qmc.Sobol(problem.dim, scramble=True, seed=0).random(points)
    vals = problem.values(pts)
    return float(vals.max() - vals.min())


@functools.lru_cache(maxsize=32)
def _build(dim: int, lengthscale: float, instance: int, num_features: int) -> GPSampleProblem:
    return GPSampleProblem(dim, lengthscale, instance, num_features)


def make_gp_sample(
    dim: int,
    lengthscale: float,
    instance: int = 0,
    num_features: int = DEFAULT_FEATURES,
) -> GPSampleProblem:
    """The GP sample path (dim, lengthscale, instance) with ``num_features`` features.

    Raises:
        SettingError: naming ``dim``, ``lengthscale``, ``instance`` or ``num_features``.
    """
    d = check_int("dim", dim)
    ls = check_float("lengthscale", lengthscale, minimum=0.0, minimum_open=True)
    inst = check_int("instance", instance, minimum=0)
    n = check_int("num_features", num_features)
    return _build(d, ls, inst, n)
