"""Experiment specs: the paper's results as problems × algorithms × variants × seeds (paper
Sec. 6, App. D).

A spec is a YAML file (the bundled ones are ``localpbo_core/experiments/*.yaml``;
:func:`spec_path` finds them by name). Every key is checked; a refused spec raises
:class:`~localpbo_core.validation.SettingError` whose ``field`` is the path of the key, e.g.
``algorithms[2].options.line_search`` or ``seeds``::

    schema: localpbo/experiment/v1
    name: synthetic                  # [A-Za-z0-9][A-Za-z0-9_.-]*
    paper: Sec. 6, App. D.5          # free text: which result this reproduces
    description: ...                 # free text (optional)
    seeds: 0-29                      # "0-29", "0,1,5-7" or a list of integers >= 0
    settings:                        # run settings shared by every run (all optional)
      initial_design: 2              # an integer, "<k>d" or "<k>d+<c>" (k d + c, d = the
                                     # problem's dimension)
      budget: null                   # null (initial design + 10 d), an integer, "<k>d(+<c>)"
      noise_fraction: 0.1
    within_model: false              # true: every algorithm that takes the option gets
                                     # hyperparameters = the problem's true ones (App. D.4),
                                     # in the duel likelihood's units (see below)
    problems:
      - problem: gp_sample           # registry name
        label: gp8_l0.1              # required when options are given; default: the name
        options: {dim: 8, lengthscale: 0.1, instance: "{seed}"}
    algorithms:
      - algorithm: prefsqp           # an algorithm, or a preset (localpbo_core.presets:
                                     # its algorithm and options)
        label: prefsqp_full          # default: the algorithm or preset name
        options: {line_search: full} # joined to a preset's (which must not change)
    variants:                        # optional: settings per variant (e.g. noise levels)
      - label: noise0.05
        settings: {noise_fraction: 0.05}

The string ``"{seed}"`` as a problem option value is replaced by the run seed (each seed its
own GP sample path, the same for every algorithm, so runs stay paired by seed).

**Matched initial data**: the shared initial design depends only on the run seed and the
problem dimension (``PreferenceOptimizer``), so every algorithm of a seed starts from the same
points (App. D.1).

**Within model** (App. D.4): the problem's kernel hyperparameters (``hyperparameters`` of a
:class:`~localpbo_core.problems.gp_samples.GPSampleProblem`) are those of ``f``, while every
model-based algorithm models duels with the BoTorch convention of an implicit noise std of 1
(eq. (5): ``Phi((u(x^+) - u(x^-)) / sqrt(2))``; the paper's settings table: "implicit sigma = 1
and adjusted output scale"). The oracle answers ``Phi((f(x^+) - f(x^-)) / (sqrt(2) sigma_n))``
(eqs. (2)-(3), ``sigma_n = noise_fraction * value_range``), so the utility the algorithms model
is ``u = f / sigma_n`` and its true kernel has the same lengthscale and outputscale
``s / sigma_n^2`` (:func:`duel_hyperparameters`). A within-model spec with noise-free duels is
refused (the outputscale would be infinite).

**Validation** happens at load: keys, names, labels (unique, usable in file names), seeds;
then every (problem, algorithm, variant) is built for the first seed exactly as it will run
(:class:`~localpbo_core.session.Session`: problem options, algorithm options, budget, noise),
so a spec that loads runs.
"""

from __future__ import annotations

import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from localpbo_core.settings import DEFAULT_NOISE_FRACTION, RunSettings, SettingError

if TYPE_CHECKING:
    from localpbo_core.problems.base import Problem

SCHEMA = "localpbo/experiment/v1"
SPEC_DIR = Path(__file__).resolve().parent
LABEL = re.compile(r"^[A-Za-z0-9](?:[A-Za-z0-9.-]|_(?!_))*$")
"""Labels: letters, digits, ``.``, ``-`` and single ``_`` (``__`` separates them in ids)."""
SEED_TOKEN = "{seed}"

_TOP_KEYS = (
    "schema",
    "name",
    "paper",
    "description",
    "seeds",
    "settings",
    "within_model",
    "problems",
    "algorithms",
    "variants",
)
_SETTING_KEYS = ("initial_design", "budget", "noise_fraction")
_PER_DIM = re.compile(r"^\s*(\d+)\s*d\s*(?:\+\s*(\d+)\s*)?$")


@dataclass(frozen=True)
class RunLabels:
    """Which run of a spec a run is: the spec, its labels and seed, and whether its problem
    is within model."""

    spec: str
    problem_label: str
    algorithm_label: str
    variant: str
    seed: int
    within_model: bool


@dataclass(frozen=True)
class PlannedRun(RunLabels):
    """One run of a spec: its labels, seed and fully resolved settings."""

    settings: RunSettings

    @property
    def run_id(self) -> str:
        """``<problem>__<algorithm>[__<variant>]__seed<k>`` (unique within a spec)."""
        parts = [self.problem_label, self.algorithm_label]
        if self.variant:
            parts.append(self.variant)
        return "__".join([*parts, f"seed{self.seed}"])

    def describe(self) -> dict[str, Any]:
        """The labels as stored with a finished run."""
        return {
            "spec": self.spec,
            "run_id": self.run_id,
            "problem_label": self.problem_label,
            "algorithm_label": self.algorithm_label,
            "variant": self.variant,
            "seed": self.seed,
            "within_model": self.within_model,
        }


@dataclass(frozen=True)
class _Entry:
    label: str
    name: str
    options: dict[str, Any] = field(default_factory=dict)
    settings: dict[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class ExperimentSpec:
    """A loaded, validated spec (see the module docstring)."""

    name: str
    paper: str
    description: str
    seeds: tuple[int, ...]
    settings: dict[str, Any]
    within_model: bool
    problems: tuple[_Entry, ...]
    algorithms: tuple[_Entry, ...]
    variants: tuple[_Entry, ...]
    path: str = ""

    def groups(self) -> list[tuple[str, str, str]]:
        """The groups as (problem, variant, algorithm) labels, in spec order: the runs of
        :meth:`runs` without their seeds."""
        return [
            (p.label, v.label, a.label)
            for p in self.problems
            for v in self.variants
            for a in self.algorithms
        ]

    def runs(
        self,
        problems: Sequence[str] | None = None,
        algorithms: Sequence[str] | None = None,
        variants: Sequence[str] | None = None,
        seeds: Sequence[int] | None = None,
    ) -> list[PlannedRun]:
        """The runs in spec order: problem, variant, algorithm, seed (innermost).

        The filters keep the runs whose labels and seed they list (None: all); only those are
        resolved, so a slice of a within-model spec builds only its own problems.
        """

        def kept(entries: tuple[_Entry, ...], labels: Sequence[str] | None) -> list[_Entry]:
            return [e for e in entries if not labels or e.label in labels]

        out = []
        dims: dict[str, int] = {}
        for p in kept(self.problems, problems):
            for v in kept(self.variants, variants):
                for a in kept(self.algorithms, algorithms):
                    for seed in [s for s in self.seeds if not seeds or s in seeds]:
                        settings = _resolve(self, p, a, v, seed, dims)
                        out.append(
                            PlannedRun(
                                self.name,
                                p.label,
                                a.label,
                                v.label,
                                seed,
                                self.within_model,
                                settings,
                            )
                        )
        return out


def spec_path(name_or_path: str | Path) -> Path:
    """A path as given if it exists, else the bundled spec ``<name>.yaml``."""
    path = Path(name_or_path)
    if path.exists():
        return path
    bundled = SPEC_DIR / f"{name_or_path}.yaml"
    if bundled.exists():
        return bundled
    names = ", ".join(sorted(p.stem for p in SPEC_DIR.glob("*.yaml")))
    raise SettingError(
        "spec", f"no file {str(name_or_path)!r} and no bundled spec; bundled: {names}"
    )


def load_spec(name_or_path: str | Path, validate: bool = True) -> ExperimentSpec:
    """Load and validate a spec file (see the module docstring).

    Raises:
        SettingError: ``field`` is the path of the refused key.
    """
    import yaml

    path = spec_path(name_or_path)
    try:
        doc = yaml.safe_load(path.read_text())
    except yaml.YAMLError as exc:
        raise SettingError("spec", f"{path}: not valid YAML ({exc})") from None
    spec = parse_spec(doc, str(path))
    if validate:
        validate_runs(spec)
    return spec


def parse_spec(doc: object, path: str = "") -> ExperimentSpec:
    """Check the structure of a parsed spec document (no problem or algorithm is built)."""
    from localpbo_core.optimizers.registry import available_optimizers
    from localpbo_core.presets import available_presets, expand
    from localpbo_core.problems import available_problems

    top = _mapping("spec", doc)
    _known_keys("", top, _TOP_KEYS)
    for required in ("schema", "name", "seeds", "problems", "algorithms"):
        if required not in top:
            raise SettingError(required, "is required")
    if top["schema"] != SCHEMA:
        raise SettingError("schema", f"must be {SCHEMA!r}, got {top['schema']!r}")
    name = _label("name", top["name"])
    paper = _text("paper", top.get("paper", ""))
    description = _text("description", top.get("description", ""))
    seeds = _seeds(top["seeds"])
    settings = _settings("settings", top.get("settings", {}))
    within = top.get("within_model", False)
    if not isinstance(within, bool):
        raise SettingError("within_model", f"must be true or false, got {within!r}")

    problems = []
    for i, item in enumerate(_list("problems", top["problems"])):
        where = f"problems[{i}]"
        entry = _mapping(where, item)
        _known_keys(where, entry, ("problem", "label", "options"))
        pname = _name(f"{where}.problem", entry.get("problem"), available_problems())
        options = dict(_mapping(f"{where}.options", entry.get("options", {})))
        if options and "label" not in entry:
            raise SettingError(f"{where}.label", "is required when options are given")
        label = _label(f"{where}.label", entry.get("label", pname))
        for key, value in options.items():
            if isinstance(value, str) and "{" in value and value != SEED_TOKEN:
                raise SettingError(
                    f"{where}.options.{key}", f"the only placeholder is {SEED_TOKEN!r}"
                )
        problems.append(_Entry(label, pname, options))

    algorithms = []
    for i, item in enumerate(_list("algorithms", top["algorithms"])):
        where = f"algorithms[{i}]"
        entry = _mapping(where, item)
        _known_keys(where, entry, ("algorithm", "label", "options"))
        aname = _name(
            f"{where}.algorithm",
            entry.get("algorithm"),
            available_optimizers() + available_presets(),
        )
        label = _label(f"{where}.label", entry.get("label", aname))
        try:
            aname, options = expand(
                aname, dict(_mapping(f"{where}.options", entry.get("options", {})))
            )
        except SettingError as exc:
            raise SettingError(
                f"{where}.options.{exc.field.partition('.')[2]}", exc.reason
            ) from None
        algorithms.append(_Entry(label, aname, options))

    variants = []
    if "variants" in top:
        for i, item in enumerate(_list("variants", top["variants"])):
            where = f"variants[{i}]"
            entry = _mapping(where, item)
            _known_keys(where, entry, ("label", "settings"))
            if "label" not in entry:
                raise SettingError(f"{where}.label", "is required")
            label = _label(f"{where}.label", entry["label"])
            variants.append(
                _Entry(
                    label, "", settings=_settings(f"{where}.settings", entry.get("settings", {}))
                )
            )
    else:
        variants.append(_Entry("", ""))

    for kind, entries in (
        ("problems", problems),
        ("algorithms", algorithms),
        ("variants", variants),
    ):
        seen: set[str] = set()
        for i, e in enumerate(entries):
            if e.label in seen:
                raise SettingError(f"{kind}[{i}].label", f"repeated label {e.label!r}")
            seen.add(e.label)
    return ExperimentSpec(
        name,
        paper,
        description,
        seeds,
        settings,
        within,
        tuple(problems),
        tuple(algorithms),
        tuple(variants),
        path,
    )


def duel_hyperparameters(
    problem: Problem, noise_fraction: float, label: str = ""
) -> dict[str, float]:
    """The true hyperparameters of the utility the algorithms model, ``u = f / sigma_n``.

    ``problem.hyperparameters`` is the kernel of ``f`` (lengthscale ``l``, outputscale ``s``);
    with ``sigma_n = noise_fraction * problem.value_range`` the kernel of ``u`` has lengthscale
    ``l`` and outputscale ``s / sigma_n^2`` (module docstring, "Within model").

    Raises:
        SettingError: (field ``within_model``) the problem has no true hyperparameters, or the
            duels are noise-free (``sigma_n = 0``: no finite outputscale).
    """
    from localpbo_core.problems.oracle import noise_std

    name = label or problem.name
    hp = getattr(problem, "hyperparameters", None)
    if not isinstance(hp, Mapping):
        raise SettingError("within_model", f"problem {name!r} has no true hyperparameters to give")
    sigma = noise_std(problem, noise_fraction)
    if not sigma > 0:
        raise SettingError(
            "within_model",
            f"problem {name!r} with noise_fraction {noise_fraction!r}: noise-free duels have no "
            "finite outputscale in the duel likelihood's units",
        )
    return {
        "lengthscale": float(hp["lengthscale"]),
        "outputscale": float(hp["outputscale"]) / sigma**2,
    }


def validate_runs(spec: ExperimentSpec) -> None:
    """Build every (problem, algorithm, variant) of the first seed as it will run.

    Raises:
        SettingError: ``field`` names the spec entry, e.g. ``algorithms[1].options.batch_size``.
    """
    from localpbo_core.session import Session, build_problem

    seed = spec.seeds[0]
    dims: dict[str, int] = {}
    for pi, p in enumerate(spec.problems):
        problem = None
        for vi, v in enumerate(spec.variants):
            for ai, a in enumerate(spec.algorithms):
                settings = _resolve(spec, p, a, v, seed, dims, pi, ai, vi)
                try:
                    if problem is None:
                        problem = build_problem(settings)
                    Session(settings, problem)
                except SettingError as exc:
                    raise _locate(exc, pi, ai, vi, spec) from None


def _locate(exc: SettingError, pi: int, ai: int, vi: int, spec: ExperimentSpec) -> SettingError:
    head, _, rest = exc.field.partition(".")
    if head == "problem_options":
        return SettingError(f"problems[{pi}].options" + (f".{rest}" if rest else ""), exc.reason)
    if head in ("problem",):
        return SettingError(f"problems[{pi}].problem", exc.reason)
    if head == "optimizer_options":
        return SettingError(f"algorithms[{ai}].options" + (f".{rest}" if rest else ""), exc.reason)
    if head == "algorithm":
        return SettingError(f"algorithms[{ai}].algorithm", exc.reason)
    where = f"variants[{vi}].settings" if spec.variants[vi].settings else "settings"
    return SettingError(f"{where}.{exc.field}", exc.reason)


def _resolve(
    spec: ExperimentSpec,
    p: _Entry,
    a: _Entry,
    v: _Entry,
    seed: int,
    dims: dict[str, int],
    pi: int = 0,
    ai: int = 0,
    vi: int = 0,
) -> RunSettings:
    """The RunSettings of one run (placeholders, per-dimension values, within-model)."""
    from localpbo_core.optimizers.registry import optimizer_options
    from localpbo_core.session import build_problem

    problem_options = {k: seed if val == SEED_TOKEN else val for k, val in p.options.items()}
    merged = {**spec.settings, **v.settings}
    options = dict(a.options)
    needs_dim = any(isinstance(merged.get(k), str) for k in ("initial_design", "budget"))
    wants_hp = spec.within_model and "hyperparameters" in optimizer_options(a.name)
    problem = None
    if needs_dim or wants_hp:
        key = f"{p.label}/{seed}"
        if key not in dims or wants_hp:
            try:
                problem = build_problem(
                    RunSettings("sobol", p.name, problem_options=problem_options)
                )
            except SettingError as exc:
                raise _locate(exc, pi, ai, vi, spec) from None
            dims[key] = problem.dim
    if wants_hp and "hyperparameters" not in options:
        assert problem is not None  # built above whenever wants_hp
        fraction = merged.get("noise_fraction", DEFAULT_NOISE_FRACTION)
        options["hyperparameters"] = duel_hyperparameters(problem, fraction, p.label)
    values: dict[str, Any] = {}
    for key in _SETTING_KEYS:
        if key not in merged:
            continue
        value = merged[key]
        if isinstance(value, str) and key in ("initial_design", "budget"):
            match = _PER_DIM.match(value)
            assert match is not None  # checked by _settings
            value = int(match.group(1)) * dims[f"{p.label}/{seed}"] + int(match.group(2) or 0)
        values[key] = value
    try:
        return RunSettings(
            algorithm=a.name,
            problem=p.name,
            seed=seed,
            optimizer_options=options,
            problem_options=problem_options,
            **values,
        )
    except SettingError as exc:
        raise _locate(exc, pi, ai, vi, spec) from None


# ---------------------------------------------------------------------- small checks
def _mapping(field: str, value: object) -> Mapping[str, Any]:
    if not isinstance(value, Mapping):
        raise SettingError(field, f"must be a mapping, got {value!r}")
    for key in value:
        if not isinstance(key, str):
            raise SettingError(field, f"keys must be strings, got {key!r}")
    return value


def _list(field: str, value: object) -> list[Any]:
    if not isinstance(value, list) or not value:
        raise SettingError(field, f"must be a non-empty list, got {value!r}")
    return value


def _known_keys(where: str, entry: Mapping[str, Any], allowed: Sequence[str]) -> None:
    for key in entry:
        if key not in allowed:
            path = f"{where}.{key}" if where else key
            raise SettingError(path, f"unknown key; valid: {', '.join(allowed)}")


def _text(field: str, value: object) -> str:
    if not isinstance(value, str):
        raise SettingError(field, f"must be text, got {value!r}")
    return value


def _label(field: str, value: object) -> str:
    if not isinstance(value, str) or not LABEL.match(value):
        raise SettingError(
            field,
            f"must match {LABEL.pattern} (letters, digits, '.', '-', single '_'), got {value!r}",
        )
    return value


def _name(field: str, value: object, available: Sequence[str]) -> str:
    if not isinstance(value, str) or value.strip().lower() not in available:
        raise SettingError(field, f"unknown name {value!r}; available: {', '.join(available)}")
    return value.strip().lower()


def _seeds(value: object) -> tuple[int, ...]:
    if isinstance(value, int) and not isinstance(value, bool):
        value = [value]
    if isinstance(value, str):
        from localpbo_core.arguments import parse_seeds

        try:
            seeds = parse_seeds(value)
        except ValueError:
            raise SettingError(
                "seeds", f"expected integers >= 0 such as '0-29' or '0,1,5', got {value!r}"
            ) from None
    elif isinstance(value, list) and value:
        for s in value:
            if isinstance(s, bool) or not isinstance(s, int) or s < 0:
                raise SettingError("seeds", f"must be integers >= 0, got {s!r}")
        seeds = list(value)
    else:
        raise SettingError("seeds", f"expected a range text or a list of integers, got {value!r}")
    if len(set(seeds)) != len(seeds):
        raise SettingError("seeds", "repeated seed")
    return tuple(seeds)


def _settings(field: str, value: object) -> dict[str, Any]:
    entry = dict(_mapping(field, value))
    _known_keys(field, entry, _SETTING_KEYS)
    for key in ("initial_design", "budget"):
        v = entry.get(key)
        if isinstance(v, str) and not _PER_DIM.match(v):
            raise SettingError(
                f"{field}.{key}", f"must be an integer, '<k>d' or '<k>d+<c>', got {v!r}"
            )
    return entry
