"""Named inputs of a workflow job, read back by name instead of by position.

A job that reads one kind of file for every sensor of a campaign names each input
`<kind>__<sensor>` (and `<kind>__<campaign>__<sensor>` across campaigns): the workflow's
`sensor_inputs` / `every_pair_inputs` write those names, and these functions group them again,
so no list of files is ever paired with a list of sensors by position.
"""

from __future__ import annotations

from collections.abc import Mapping

SEPARATOR = "__"


def by_sensor(inputs: Mapping[str, str], kind: str) -> dict[str, str]:
    """sensor -> file of the inputs named `<kind>__<sensor>`, in the order the inputs give them."""
    prefix = kind + SEPARATOR
    return {name[len(prefix) :]: str(path) for name, path in inputs.items() if name.startswith(prefix)}


def by_pair(inputs: Mapping[str, str], kind: str) -> dict[tuple[str, str], str]:
    """(campaign, sensor) -> file of the inputs named `<kind>__<campaign>__<sensor>`."""
    out = {}
    for key, path in by_sensor(inputs, kind).items():
        campaign, separator, sensor = key.rpartition(SEPARATOR)
        if not separator:
            raise ValueError(f"input {kind}{SEPARATOR}{key} names no campaign and sensor")
        out[(campaign, sensor)] = str(path)
    return out


def sensors(inputs: Mapping[str, str], kind: str) -> list[str]:
    """The sensors that have an input of `kind`, in order."""
    return list(by_sensor(inputs, kind))


def by_kind(inputs: Mapping[str, str]) -> dict[str, dict[str, str]]:
    """kind -> sensor -> file, for every input named `<kind>__<sensor>` (unnamed-by-sensor ones left out)."""
    kinds = dict.fromkeys(name.split(SEPARATOR)[0] for name in inputs if SEPARATOR in name)
    return {kind: by_sensor(inputs, kind) for kind in kinds}
