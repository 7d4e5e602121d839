"""Write docs/configuration.md from the workflow's configuration schema (src/remaster/data/config.schema.yaml).

Run from anywhere:  python docs/config_docs.py           (the Markdown on stdout)
                    python docs/config_docs.py --write   (replace docs/configuration.md)
tests/test_docs.py regenerates the page and fails when the file differs, so the page is never edited
by hand: change the schema's descriptions and run this script.

Every key gets a row: its path (fit/paper/samples), type, default, allowed values and description,
all taken from the schema. Defaults come from the schema only, never from config.yaml (the file a
user edits for a run).

It lives beside the page rather than in the package: remaster's modules leave files to the few that
test_architecture.FILE_ACCESS names (remaster.files among them) and the command line, and this is a
tool of the repository, not of the library.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import yaml

REPO = Path(__file__).resolve().parents[1]
SCHEMA = REPO / "src" / "remaster" / "data" / "config.schema.yaml"
PAGE = REPO / "docs" / "configuration.md"
COMMAND = "python docs/config_docs.py --write"


# JSON Schema keywords the schema uses; any other key inside a property is a slip (a comma in an unquoted
# flow-mapping description ends the description and makes the rest a key of its own).
KEYWORDS = {
    "$schema",
    "$ref",
    "description",
    "type",
    "additionalProperties",
    "properties",
    "default",
    "items",
    "pattern",
    "uniqueItems",
    "minimum",
    "maximum",
    "exclusiveMinimum",
    "exclusiveMaximum",
    "enum",
    "minItems",
    "maxItems",
    "required",
    "definitions",
}


def stray_keys(node: dict, path: str = "") -> list[str]:
    """'setting path: key' for every key of the schema's nodes that is not a JSON Schema keyword."""
    found = [f"{path or '(top)'}: {key!r}" for key in node if key not in KEYWORDS]
    for group in ("properties", "definitions"):
        for name, child in node.get(group, {}).items():
            if isinstance(child, dict):
                found += stray_keys(child, f"{path}/{name}".lstrip("/"))
    return found


def _resolve(node: dict, schema: dict) -> dict:
    """The node with a local $ref (#/definitions/...) replaced by what it points to (its own keys win)."""
    ref = node.get("$ref")
    if ref is None:
        return node
    target = schema
    for part in ref.removeprefix("#/").split("/"):
        target = target[part]
    return {**_resolve(target, schema), **{k: v for k, v in node.items() if k != "$ref"}}


def _type(node: dict) -> str:
    kinds = node.get("type", "")
    kinds = kinds if isinstance(kinds, list) else [kinds]
    names = []
    for kind in kinds:
        if kind == "array":
            items = node.get("items", {}).get("type")
            size = node.get("minItems") if node.get("minItems") == node.get("maxItems") else None
            kind = (
                "array"
                + (" of" if size or items else "")
                + (f" {size}" if size else "")
                + (f" {items}s" if items else "")
            )
        names.append(kind)
    return " or ".join(names)


def _value(value) -> str:
    return "`" + json.dumps(value) + "`"


def _allowed(node: dict) -> str:
    parts = []
    for key, sign in (("minimum", ">="), ("exclusiveMinimum", ">"), ("maximum", "<="), ("exclusiveMaximum", "<")):
        if key in node:
            parts.append(f"{sign} {node[key]}")
    if "enum" in node:
        parts.append("one of " + ", ".join(f"`{v}`" for v in node["enum"]))
    items = node.get("items", {})
    if "pattern" in items:
        parts.append(f"each matches `{items['pattern']}`")
    if node.get("uniqueItems"):
        parts.append("no repeats")
    return "; ".join(parts)


def _default(node: dict, required: bool) -> str:
    if "default" in node:
        return "" if node["default"] == {} and "properties" in node else _value(node["default"])
    return "required" if required else ""


def _cell(text: str) -> str:
    return " ".join(str(text).split()).replace("|", "\\|")


def _rows(properties: dict, required: list, prefix: str, schema: dict) -> list[str]:
    rows = []
    for name, raw in properties.items():
        node = _resolve(raw, schema)
        path = f"{prefix}{name}"
        rows.append(
            f"| `{path}` | {_type(node)} | {_default(node, name in required)} | {_cell(_allowed(node))} "
            f"| {_cell(node.get('description', ''))} |"
        )
        if "properties" in node:
            rows += _rows(node["properties"], node.get("required", []), f"{path}/", schema)
    return rows


HEADER = "| key | type | default | allowed | description |\n|---|---|---|---|---|"


def markdown(schema: dict) -> str:
    """The configuration page for `schema` (the parsed config.schema.yaml)."""
    properties = schema["properties"]
    plain = {k: v for k, v in properties.items() if "properties" not in _resolve(v, schema)}
    groups = {k: v for k, v in properties.items() if k not in plain}
    lines = [
        "# Configuration",
        "",
        f"<!-- Generated from src/remaster/data/config.schema.yaml by docs/config_docs.py: do not edit by hand. "
        f"Regenerate with `{COMMAND}`. -->",
        "",
        _cell(schema.get("description", "")),
        "",
        "The settings live in `config.yaml` at the repository root; the workflow checks them against the",
        "schema before any job runs and fills in every default below. `raw_dir`, `results_dir` and",
        "`campaigns` are often given on the command line instead:",
        "`snakemake -j2 --config raw_dir=/data/campaigns campaigns='[cell3-2024]'`.",
        "A key path `fit/paper/samples` is `samples` under `paper` under `fit` in the YAML file.",
        "What the settings mean for the results is in [methods.md](methods.md).",
        "",
        "## General",
        "",
        HEADER,
        *_rows(plain, schema.get("required", []), "", schema),
    ]
    for name, raw in groups.items():
        node = _resolve(raw, schema)
        lines += [
            "",
            f"## {name}",
            "",
            _cell(node.get("description", "")),
            "",
            HEADER,
            *_rows(node["properties"], node.get("required", []), f"{name}/", schema),
        ]
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--write", action="store_true", help=f"replace {PAGE.relative_to(REPO)} instead of printing")
    args = parser.parse_args(argv)
    schema = yaml.safe_load(SCHEMA.read_text(encoding="utf-8"))
    for stray in stray_keys(schema):
        print(
            f"warning: {SCHEMA.relative_to(REPO)}: {stray} is not a JSON Schema keyword (a description cut at a "
            "comma? quote it)",
            file=sys.stderr,
        )
    text = markdown(schema)
    if args.write:
        PAGE.write_text(text, encoding="utf-8")
    else:
        sys.stdout.write(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
