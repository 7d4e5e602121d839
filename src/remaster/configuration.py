"""The configuration's one schema: every setting of config.yaml, its check and its default.

`SCHEMA` is the file shipped with the package (remaster/data/config.schema.yaml). The workflow
validates config.yaml against it (workflow/rules/common.smk, through Snakemake, which fills in its
defaults) and `settings` does the same for a Python caller, so the defaults live in that file only.
"""

from __future__ import annotations

import copy
import functools
from collections.abc import Mapping
from importlib import resources
from typing import Any

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
