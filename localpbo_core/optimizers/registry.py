"""``make_optimizer`` / ``available_optimizers``: the single way to build an optimizer."""

from __future__ import annotations

import inspect
from collections.abc import Callable

from localpbo_core.optimizers.glisp import GLISpOptimizer
from localpbo_core.optimizers.preference_optimizer import PreferenceOptimizer
from localpbo_core.optimizers.qeubo import QEUBO
from localpbo_core.optimizers.sobol import SobolOptimizer
from localpbo_core.optimizers.turpbo import TuRPBO

_REGISTRY: dict[str, Callable[..., PreferenceOptimizer]] = {
    "sobol": SobolOptimizer,
    "turpbo": TuRPBO,
    "qeubo": QEUBO,
    "glisp": GLISpOptimizer,
}


def register_optimizer(name: str, factory: Callable[..., PreferenceOptimizer]) -> None:
    """Add an algorithm (used by later issues, e.g. GIPBO, PrefSQP)."""
    key = name.lower()
    if key in _REGISTRY:
        raise ValueError(f"algorithm: {name!r} is already registered")
    _REGISTRY[key] = factory


def available_optimizers() -> list[str]:
    """Names accepted by :func:`make_optimizer`."""
    return sorted(_REGISTRY)


def optimizer_options(name: str) -> list[str]:
    """Keyword options accepted by algorithm ``name`` (besides dim, seed, budget)."""
    factory = _lookup(name)
    params = inspect.signature(factory).parameters
    return [p for p in params if p not in ("self", "dim", "seed", "budget")]


def _lookup(name: str) -> Callable[..., PreferenceOptimizer]:
    key = str(name).lower()
    if key not in _REGISTRY:
        raise ValueError(
            f"algorithm: unknown algorithm {name!r}; available: {', '.join(available_optimizers())}"
        )
    return _REGISTRY[key]


def make_optimizer(
    name: str, dim: int, seed: int = 0, budget: int | None = None, **options: object
) -> PreferenceOptimizer:
    """Build an ask/tell optimizer.

    Args:
        name: algorithm name (see :func:`available_optimizers`), case-insensitive.
        dim: dimension d of theta in [0,1]^d.
        seed: non-negative integer seed.
        budget: total evaluations including the initial design; default ``2 + 10 d``
            (paper App. D.1, synthetic benchmarks) plus any extra initial design points.
        **options: algorithm options, e.g. ``initial_design``, ``warm_start``,
            ``batch_size``, ``acquisition``.

    Raises:
        ValueError: unknown algorithm or option (named), bad dim, budget or warm start.
    """
    factory = _lookup(name)
    allowed = optimizer_options(name)
    for key in options:
        if key not in allowed:
            raise ValueError(
                f"option {key!r}: not an option of {name!r}; allowed: {', '.join(allowed)}"
            )
    if budget is None:
        if isinstance(dim, int) and dim >= 1:
            init = options.get("initial_design", 2)
            budget = (init if isinstance(init, int) else 2) + 10 * dim
        else:
            budget = 0
    return factory(dim=dim, seed=seed, budget=budget, **options)


# --- derivative-informed local methods (issue 5: GIPBO, GIPBOr, PrefSQP; helper G) -------------
def _register_derivative_methods() -> None:
    from localpbo_core.optimizers.gipbo import GIPBO, GIPBOr
    from localpbo_core.optimizers.prefsqp import PrefSQP

    for key, factory in (("gipbo", GIPBO), ("gipbor", GIPBOr), ("prefsqp", PrefSQP)):
        _REGISTRY.setdefault(key, factory)


_register_derivative_methods()
