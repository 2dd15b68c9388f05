"""Named presets: an algorithm with options under one label, accepted wherever an algorithm
is named (``localpbo run --algorithm``, ``localpbo bench --algorithm``, the optimizer node's
``algorithm`` parameter, an experiment spec's ``algorithm`` entry).

A preset is expanded when a run's settings are built
(:class:`~localpbo_core.settings.RunSettings`): the algorithm becomes the preset's algorithm
and its options join the run's optimizer options, so the run, its stored settings and its
recorded run config are exactly those of the algorithm with the options given explicitly.
An option given explicitly as well must have the preset's value (a different one is
refused: the run would no longer be the preset).

The presets are the configured variants of the ``beyond_*`` experiment specs, which name
them by label (``algorithm: prefsqp_all``), so a spec's variant and the preset of the same
name cannot diverge. The options are documented with the algorithms (``docs/algorithms.md``,
"Beyond the paper"): PrefSQP's local steps (paper Sec. 5.2, App. C.4), GIPBO's (Sec. 5.1,
App. C.2), and the hybrid of TuRPBO's trust region (Sec. 5.3) with kernel-metric local steps.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any

from localpbo_core.validation import SettingError


@dataclass(frozen=True)
class Preset:
    """A registered algorithm and the options that configure it."""

    algorithm: str
    options: Mapping[str, Any] = field(default_factory=dict)
    description: str = ""


def _preset(algorithm: str, description: str, **options: Any) -> Preset:
    return Preset(algorithm, MappingProxyType(dict(options)), description)


PRESETS: Mapping[str, Preset] = MappingProxyType(
    {
        "hybrid_c0.5": _preset(
            "hybrid",
            "the hybrid with its handover threshold halved (on Levy 32 the default z >= 1 is "
            "never reached on 3 of 10 seeds)",
            confidence=0.5,
        ),
        "hybrid_local": _preset(
            "hybrid",
            "the hybrid handing over whenever its cooldown allows (handover_length at the trust "
            "region's largest side): local steps first, TuRPBO's region after a stall",
            handover_length=1.6,
        ),
        "hybrid_probe": _preset(
            "hybrid",
            "the hybrid stepping locally first, each local phase led by d probes (GIPBOr's random "
            "local duels, at 0.5-2 lengthscales) that inform its gradient",
            handover_length=1.6,
            probes_per_dim=1.0,
        ),
        "hybrid_probe0.5": _preset(
            "hybrid",
            "hybrid_probe with d/2 probes per local phase",
            handover_length=1.6,
            probes_per_dim=0.5,
        ),
        "hybrid_probe0.5_s0.5": _preset(
            "hybrid",
            "hybrid_probe0.5 with its probes at half the radius (0.25-1 lengthscales)",
            handover_length=1.6,
            probes_per_dim=0.5,
            probe_scale=0.5,
        ),
        "prefsqp_radius": _preset(
            "prefsqp",
            "PrefSQP sampling its gradient duels at a radius relative to the lengthscale",
            sampling_radius="lengthscale",
        ),
        "prefsqp_kernel": _preset(
            "prefsqp",
            "PrefSQP with a step of length 0.5 in the kernel metric",
            step_normalization="kernel",
        ),
        "prefsqp_duel_ls": _preset(
            "prefsqp",
            "PrefSQP whose line search evaluates and duels its points",
            line_search="duel",
        ),
        "prefsqp_gated": _preset(
            "prefsqp",
            "PrefSQP keeping a step only when it wins its duel",
            accept_step="duel",
        ),
        "prefsqp_all": _preset(
            "prefsqp",
            "PrefSQP with the lengthscale-relative radius, the kernel-metric step and the "
            "step kept only when it wins its duel",
            sampling_radius="lengthscale",
            step_normalization="kernel",
            accept_step="duel",
        ),
        "gipbo_gated": _preset(
            "gipbo",
            "GIPBO keeping a step only when it wins its duel",
            accept_step="duel",
        ),
        "gipbor_gated": _preset(
            "gipbor",
            "GIPBOr keeping a step only when it wins its duel",
            accept_step="duel",
        ),
    }
)
"""The presets by label (lower case)."""


def available_presets() -> list[str]:
    """The preset labels, sorted."""
    return sorted(PRESETS)


def expand(name: str, options: Mapping[str, Any]) -> tuple[str, dict[str, Any]]:
    """``(algorithm, options)`` for ``name``: a preset's algorithm and its options joined by
    ``options`` (preset options first, in their order); any other name as it is.

    Raises:
        SettingError: (field ``optimizer_options.<key>``) ``options`` gives an option of the
            preset another value.
    """
    preset = PRESETS.get(name.strip().lower())
    if preset is None:
        return name, dict(options)
    for key, value in options.items():
        if key in preset.options and preset.options[key] != value:
            raise SettingError(
                f"optimizer_options.{key}",
                f"preset {name!r} sets it to {preset.options[key]!r}, got {value!r} (name the "
                f"algorithm {preset.algorithm!r} to choose another value)",
            )
    return preset.algorithm, {**preset.options, **options}
