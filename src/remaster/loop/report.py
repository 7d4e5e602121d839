"""loop_closure.json as the stages after the loop closure read it: one typed view, checked once.

`loop_closure.loop_closure_stage` writes the report; the calibrated files, predictions,
comparisons, workspace accuracy, uncertainty budget, certificate and figures read the fields of
`LoopReport` (`LoopReport.read`). A missing field is an InputError naming the file and the key.
The loop's own tables, which show the selection in full (candidates, rounds, noise model), read
`details`, the report as written.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import pandas as pd

from ..errors import InputError, report_reader
from ..files import read_json
from ..units import DEG, MM


@dataclass(frozen=True, eq=False)
class LoopReport:
    """One sensor's loop closure. campaign: its name (None when not recorded); effects_added: in
    the order added; parameters: the refit's table, one row per parameter (parameter, block, mean
    and std SI, status, prior ratio...);
    payload_mass (kg) and payload_com (3,) m: the tool plate the gravity torques assumed;
    held_zero_offset_std (rad): the controller marks' tolerance on a joint no sensor sees;
    sigma_after (m); prior_dominated: parameters the data barely moved from their prior;
    unseen_by_data: parameters the data cannot see at all; closure: the closure test's verdict
    and numbers; residual_gp: the residual GP's section (None when not tried); warnings;
    details: the whole report, for the loop's own tables."""

    source: str
    campaign: str | None
    effects_added: tuple[str, ...]
    parameters: pd.DataFrame
    payload_mass: float
    payload_com: tuple[float, float, float]
    held_zero_offset_std: float
    sigma_after: float
    prior_dominated: tuple[str, ...]
    unseen_by_data: tuple[str, ...]
    closure: Mapping[str, Any]
    residual_gp: Mapping[str, Any] | None
    warnings: tuple[str, ...]
    details: Mapping[str, Any]

    @classmethod
    def of(cls, content: Mapping, source: str = "loop_closure.json") -> "LoopReport":
        """From the JSON content; a missing key is an InputError naming the file and the key."""
        get = report_reader(content, source, "missing in the loop-closure report")
        parameters, effects = get("refit", "parameters"), get("effects_added")
        if not isinstance(parameters, list):
            raise InputError("not a list of parameters", file=source, key="refit/parameters")
        if not isinstance(effects, list):
            raise InputError("not a list of effects", file=source, key="effects_added")
        return cls(source=source, campaign=content.get("campaign"), effects_added=tuple(str(e) for e in effects),
                   parameters=pd.DataFrame(parameters),
                   payload_mass=float(get("settings", "payload_mass_kg")),
                   payload_com=tuple(float(v) for v in get("settings", "payload_com_m")),
                   held_zero_offset_std=float(get("settings", "priors", "std_display_units",
                                                  "held_zero_offset_deg")) * DEG,
                   sigma_after=float(get("sigma_after_mm")) * MM,
                   prior_dominated=tuple(get("prior_dominated")),
                   unseen_by_data=tuple(get("identifiability", "dropped")),
                   closure=dict(get("closure")), residual_gp=content.get("residual_gp"),
                   warnings=tuple(get("warnings")), details=content)

    @classmethod
    def read(cls, path) -> "LoopReport":
        """From loop_closure.json; InputError naming the file, and the key when one is missing."""
        return cls.of(read_json(path), source=str(path))
