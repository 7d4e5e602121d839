"""The configuration's one schema: every setting of config.yaml, its check and its default.

`SCHEMA` is the file shipped with the package (remaster/data/config.schema.yaml). The workflow
validates config.yaml against it (workflow/rules/common.smk, through Snakemake, which fills in its
defaults) and `settings` does the same for a Python caller, so the defaults live in that file only.
`workflow_run` checks what the schema cannot (the paths, burn-ins shorter than their runs) and lists
the campaigns of a run: the workflow calls it on the validated configuration.
"""

from __future__ import annotations

import copy
import functools
import os
from collections.abc import Mapping
from importlib import resources
from pathlib import Path
from typing import Any, NamedTuple

from .errors import InputError
from .files import read_yaml

SCHEMA = resources.files(__package__) / "data" / "config.schema.yaml"


@functools.cache
def _schema() -> dict:
    return read_yaml(SCHEMA)


def _filling_validator(schema: dict):
    """The schema's validator that also sets each missing property to the schema's default, as
    Snakemake's `validate` does (jsonschema's documented extension): a default object is then
    validated, and so filled, in turn."""
    from jsonschema import Draft202012Validator, validators

    check_properties = Draft202012Validator.VALIDATORS["properties"]

    def set_defaults(validator, properties, instance, subschema):
        for name, property_schema in properties.items():
            if "default" in property_schema and isinstance(instance, dict):
                instance.setdefault(name, property_schema["default"])
        yield from check_properties(validator, properties, instance, subschema)

    return validators.extend(Draft202012Validator, {"properties": set_defaults})(schema)


def settings(overrides: Mapping[str, Any] | None = None) -> dict:
    """The full configuration: `overrides` (config.yaml's content, or any part of it, e.g.
    {'loop_closure': {'mcmc': None}}) checked against the schema, with the schema's default for
    every key it leaves out, nested sections included. The overrides are not changed. A value the
    schema refuses is an InputError naming its key (e.g. 'loop_closure/cv_folds')."""
    from jsonschema import ValidationError

    config = copy.deepcopy(dict(overrides or {}))
    try:
        _filling_validator(copy.deepcopy(_schema())).validate(config)
    except ValidationError as error:
        key = "/".join(str(part) for part in error.absolute_path) or None
        raise InputError(error.message, file="settings", key=key) from None
    return config


class WorkflowRun(NamedTuple):
    """What a run of the workflow reads and writes: its folders (normalised paths, as given) and its
    campaigns, in the order it processes them."""

    raw: str
    results: str
    campaigns: list[str]


def workflow_run(config: Mapping[str, Any], config_files: str) -> WorkflowRun:
    """The folders and campaigns of a workflow run, from its configuration validated against the
    schema (defaults filled in: `settings`, or Snakemake's `validate`), after the checks the schema
    cannot make. Relative paths are taken from the working folder (the workflow's: the repository
    root) and may not lead out of it (`..`): a folder elsewhere is given by its absolute path, e.g.
    --config raw_dir=/data/campaigns. Without `campaigns`, every folder of raw_dir that holds a
    campaign.yaml, sorted by name.

    Raises InputError (a ValueError) '<config_files>: <key>: <what is wrong>', `config_files` naming
    the configuration (the workflow's config files, or --config) and the key, for: a path setting
    that is empty or leads outside the repository; a raw_dir that is not a directory; a results_dir
    that is a file, or that overlaps raw_dir; a sampler's burn-in not below its run (fit/paper,
    fit/default, fit/emcee, loop_closure/mcmc); a campaign of `campaigns` without
    <raw_dir>/<name>/campaign.yaml; a raw_dir holding no campaign; a campaign both in the run and
    in failed_campaigns."""

    def error(key: str, message: str) -> InputError:
        return InputError(message, file=config_files, key=key)

    def checked_path(key: str) -> str:
        value = config[key]
        if not value.strip():
            raise error(key, "is empty")
        if not os.path.isabs(value) and os.path.normpath(value).split(os.sep)[0] == "..":
            raise error(
                key,
                f"{value!r} leads outside the repository; relative paths are taken from the "
                f"repository root: give an absolute path for a folder elsewhere",
            )
        return os.path.normpath(value)

    raw, results = checked_path("raw_dir"), checked_path("results_dir")
    if not Path(raw).is_dir():
        raise error("raw_dir", f"{raw!r} is not a directory (it should hold one folder per campaign)")
    if Path(results).exists() and not Path(results).is_dir():
        raise error("results_dir", f"{results!r} exists and is not a directory")
    raw_path, results_path = Path(raw).resolve(), Path(results).resolve()
    if raw_path == results_path or raw_path in results_path.parents or results_path in raw_path.parents:
        raise error(
            "results_dir",
            f"{results!r} overlaps raw_dir {raw!r}: generated files and campaign data must live in separate folders",
        )
    # every sampler's burn-in shorter than its run: the paper model's three and the loop closure's refit
    runs = [
        (f"fit/{method}", config["fit"][method], length)
        for method, length in (("paper", "samples"), ("default", "samples"), ("emcee", "steps"))
    ]
    for key, sampler, length in runs + [("loop_closure/mcmc", config["loop_closure"]["mcmc"], "samples")]:
        if sampler["burn_in"] >= sampler[length]:
            raise error(
                f"{key}/burn_in",
                f"{sampler['burn_in']} is not below {key}/{length} = {sampler[length]}: no sample would be kept",
            )
    if config["campaigns"]:
        missing = [c for c in config["campaigns"] if not Path(raw, c, "campaign.yaml").is_file()]
        if missing:
            raise error("campaigns", f"no {raw}/<name>/campaign.yaml for {', '.join(missing)}")
        campaigns = list(config["campaigns"])
    else:
        campaigns = sorted(p.parent.name for p in Path(raw).glob("*/campaign.yaml"))
        if not campaigns:
            raise error("raw_dir", f"{raw!r} holds no campaign folder (<name>/campaign.yaml): nothing to process")
    # the campaigns that failed in the run this one completes (Snakefile: onerror): not also run here
    both = sorted(set(config["failed_campaigns"]) & set(campaigns))
    if both:
        raise error(
            "failed_campaigns",
            f"{', '.join(both)} also in the run's campaigns: "
            "failed_campaigns is set by the workflow for the campaigns it leaves out",
        )
    return WorkflowRun(raw, results, campaigns)
