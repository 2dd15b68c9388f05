"""``make_optimizer`` / ``available_optimizers``: the single way to build an optimizer.

Algorithms are registered by import path and imported only when built or inspected, so
listing them (``localpbo bench --help``) loads neither torch nor BoTorch.

An algorithm's options are the keyword parameters of its factory (besides dim, seed, budget),
in order. A class whose ``__init__`` takes ``**options: Unpack[SomeOptions]`` and hands them
on to its base class has the keys of that ``TypedDict`` as options in that place, each with
the default of the nearest base class whose ``__init__`` names it.
"""

from __future__ import annotations

import importlib
import inspect
import typing
from collections.abc import Callable
from typing import TYPE_CHECKING

from localpbo_core.settings import DEFAULT_INITIAL_DESIGN, SettingError, default_budget

if TYPE_CHECKING:
    from localpbo_core.optimizers.preference_optimizer import PreferenceOptimizer

Factory = Callable[..., "PreferenceOptimizer"]

_REGISTRY: dict[str, str | Factory] = {
    "sobol": "localpbo_core.optimizers.sobol:SobolOptimizer",
    "turpbo": "localpbo_core.optimizers.turpbo:TuRPBO",
    "qeubo": "localpbo_core.optimizers.qeubo:QEUBO",
    "glisp": "localpbo_core.optimizers.glisp:GLISpOptimizer",
    "gipbo": "localpbo_core.optimizers.gipbo:GIPBO",
    "gipbor": "localpbo_core.optimizers.gipbo:GIPBOr",
    "prefsqp": "localpbo_core.optimizers.prefsqp:PrefSQP",
    "hbei": "localpbo_core.optimizers.hbei:HBEI",
    "hybrid": "localpbo_core.optimizers.hybrid:Hybrid",
}

_RUN_ARGUMENTS = ("self", "dim", "seed", "budget")


def register_optimizer(name: str, factory: Factory | str) -> None:
    """Add an algorithm: a factory, or its import path ``"package.module:Name"``."""
    key = name.lower()
    if key in _REGISTRY:
        raise SettingError("algorithm", f"{name!r} is already registered")
    _REGISTRY[key] = factory


def available_optimizers() -> list[str]:
    """Names accepted by :func:`make_optimizer`."""
    return sorted(_REGISTRY)


def optimizer_options(name: str) -> list[str]:
    """Keyword options accepted by algorithm ``name`` (besides dim, seed, budget)."""
    return [p.name for p in _options(_lookup(name))]


def optimizer_defaults(name: str) -> dict[str, object]:
    """Default value of each keyword option of algorithm ``name`` that has one (besides dim,
    seed, budget): the options a run gets when it does not name them."""
    return {p.name: p.default for p in _options(_lookup(name)) if p.default is not p.empty}


def _options(factory: Factory) -> list[inspect.Parameter]:
    """The keyword parameters of ``factory`` besides the run arguments, an
    ``Unpack[TypedDict]`` variadic keyword standing for its keys (module docstring)."""
    options: list[inspect.Parameter] = []
    for p in inspect.signature(factory).parameters.values():
        if p.name in _RUN_ARGUMENTS:
            continue
        if p.kind is p.VAR_KEYWORD and isinstance(factory, type):
            init = next(vars(c)["__init__"] for c in factory.__mro__ if "__init__" in vars(c))
            options.extend(_inherited(factory, key) for key in _unpacked_keys(init, p))
        elif p.kind in (p.POSITIONAL_OR_KEYWORD, p.KEYWORD_ONLY):
            options.append(p)
    return options


def _unpacked_keys(init: Callable[..., object], p: inspect.Parameter) -> list[str]:
    """The keys of the ``TypedDict`` in ``**p: Unpack[TypedDict]`` of ``init``."""
    annotation = p.annotation
    if isinstance(annotation, str):
        annotation = eval(annotation, getattr(init, "__globals__", {}))
    if typing.get_origin(annotation) is not typing.Unpack:
        raise TypeError(f"**{p.name} of {init.__qualname__} is not Unpack[TypedDict]")
    (options,) = typing.get_args(annotation)
    return list(options.__annotations__)


def _inherited(cls: type, key: str) -> inspect.Parameter:
    """Option ``key`` as the nearest base class of ``cls`` whose ``__init__`` names it."""
    for base in cls.__mro__[1:]:
        if "__init__" not in vars(base):
            continue
        p = inspect.signature(vars(base)["__init__"]).parameters.get(key)
        if p is not None and p.kind in (p.POSITIONAL_OR_KEYWORD, p.KEYWORD_ONLY):
            return p
    raise TypeError(f"no base class of {cls.__qualname__} names option {key!r}")


def _lookup(name: str) -> Factory:
    key = str(name).lower()
    if key not in _REGISTRY:
        raise SettingError(
            "algorithm",
            f"unknown algorithm {name!r}; available: {', '.join(available_optimizers())}",
        )
    entry = _REGISTRY[key]
    if isinstance(entry, str):
        module, _, attr = entry.partition(":")
        entry = getattr(importlib.import_module(module), attr)
        _REGISTRY[key] = entry
    return entry


def make_optimizer(
    name: str, dim: int, seed: int = 0, budget: int | None = None, **options: object
) -> PreferenceOptimizer:
    """Build an ask/tell optimizer.

    Args:
        name: algorithm name (see :func:`available_optimizers`), case-insensitive.
        dim: dimension d of theta in [0,1]^d.
        seed: non-negative integer seed.
        budget: total evaluations including the initial design; default
            :func:`~localpbo_core.settings.default_budget` (``initial design + 10 d``, paper
            App. D.1).
        **options: algorithm options, e.g. ``initial_design``, ``warm_start``,
            ``batch_size``, ``acquisition``.

    Raises:
        SettingError: unknown algorithm or option (``field`` names it).
        ValueError: a bad value of dim, budget, warm start or an option (named).
    """
    from localpbo_core.threads import use_fast_threads

    factory = _lookup(name)
    allowed = optimizer_options(name)
    for key in options:
        if key not in allowed:
            raise SettingError(key, f"not an option of {name!r}; allowed: {', '.join(allowed)}")
    if budget is None:
        if isinstance(dim, int) and dim >= 1:
            init = options.get("initial_design", DEFAULT_INITIAL_DESIGN)
            budget = default_budget(dim, init if isinstance(init, int) else DEFAULT_INITIAL_DESIGN)
        else:
            budget = 0
    use_fast_threads()
    return factory(dim=dim, seed=seed, budget=budget, **options)
