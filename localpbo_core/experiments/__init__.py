"""Experiment specs (``*.yaml`` here, one per result of the paper) and their loader
(:mod:`.spec`); ``localpbo sweep SPEC`` runs one, ``localpbo report`` summarises the results."""

from .spec import ExperimentSpec, PlannedRun, load_spec, parse_spec, spec_path

__all__ = ["ExperimentSpec", "PlannedRun", "load_spec", "parse_spec", "spec_path"]
