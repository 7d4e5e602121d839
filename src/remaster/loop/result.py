"""loop_closure.json, typed: the loop closure's report of one sensor as `loop_closure.close_loop` makes
it, `write` writes it and every later stage reads it (`LoopReport.read`, checked once).

The fields are the file's top-level keys, with their units in their names (mm); the properties
give what the later stages use in SI. The file is written with sorted keys, so its bytes depend on
the values only. Reading a file that lacks a key the later stages need (or any field) is an
InputError naming the file and the key.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, fields
from functools import cached_property
from typing import Any

import pandas as pd

from ..errors import InputError, report_reader
from ..files import read_json, write_json
from ..inference.gp.kernels import Hyperparameters
from ..units import DEG, MM
from .sides import sides_of

NOT_WRITTEN = ("source",)  # where the report was read from: not part of the file
# written when known: campaign (`loop_closure_stage` sets it; `close_loop` alone does not) and
# harmonics (when the joint_harmonics block was added); model_error_share (absent in files written
# before it existed: read as not computed)
OPTIONAL = ("campaign", "harmonics", "model_error_share")


@dataclass(frozen=True, eq=False)
class LoopReport:
    """One sensor's loop closure.

    sensor, campaign (None when not recorded); evidence, selection_data: what the selection used
    (sentences); settings: `LoopSettings.report()`; effects_added: in the order added;
    explained_fraction_when_added: {effect: share of the residual it explained when added};
    candidates: {candidate: [its scores in each round, with the round number]}; rounds: ({'round',
    'model', 'added'}, ...); validation_rmse_before_mm, validation_rmse_after_mm, sigma_before_mm,
    sigma_after_mm (mm); before, after: {set: accuracy measures (mm)}; identifiability: the final
    model's reduction ({'dropped', 'weak', ...}); prior_dominated: parameters the data barely moved
    from their prior; warnings; refit: {'mode', 'mcmc', 'parameters'} (the MCMC refit, and the
    parameter table as records); zero_offset_shifts: how far each zero-offset moved; closure: the
    closure test's verdict and numbers; residual_gp: the residual GP's section (None when not
    tried); noise_model: the laser tracker's noise model chosen or why not offered; gross_errors:
    the screen of every row with the final model (`remaster.loop.gross`): 'optimization' and
    'validation' the table rows (ints) flagged as gross errors and left out (the optimization rows
    are the ones the final model was fitted without), with the level, the rule, each set's screen,
    the provisional rows and those restored, and the accuracy with the flagged rows
    (`screened_selection.gross_report`); between_design: {'paper', 'loop': `jackknife.zero_offset_jackknife`}
    the zero-offsets' spread across designs of the zero-offset model and the final model;
    model_error_share: what a residual field the final model lacks moves its zero-offsets by
    (`model_error_share.zero_offset_model_error`; None when not recorded); harmonics: the joints and orders of `joint_harmonics` the data support, with each
    named f_j and its band (`remaster.loop.harmonics`; None when the block was not added); source: the file it was read from (not written)."""

    sensor: str
    evidence: str
    selection_data: str
    settings: Mapping[str, Any]
    effects_added: tuple[str, ...]
    explained_fraction_when_added: Mapping[str, float]
    candidates: Mapping[str, list]
    rounds: tuple[Mapping[str, Any], ...]
    validation_rmse_before_mm: float
    validation_rmse_after_mm: float
    sigma_before_mm: float
    sigma_after_mm: float
    before: Mapping[str, Mapping[str, Any]]
    after: Mapping[str, Mapping[str, Any]]
    identifiability: Mapping[str, Any]
    prior_dominated: tuple[str, ...]
    warnings: tuple[str, ...]
    refit: Mapping[str, Any]
    zero_offset_shifts: tuple[Mapping[str, Any], ...]
    closure: Mapping[str, Any]
    residual_gp: Mapping[str, Any] | None
    noise_model: Mapping[str, Any]
    gross_errors: Mapping[str, Any]
    between_design: Mapping[str, Any]
    campaign: str | None = None
    harmonics: Mapping[str, Any] | None = None
    model_error_share: Mapping[str, Any] | None = None
    source: str = "loop_closure.json"

    # ----------------------------------------------------------------------- what the later stages use

    @cached_property
    def parameters(self) -> pd.DataFrame:
        """The refit's table, one row per parameter (parameter, block, mean and std SI, status, prior ratio...)."""
        return pd.DataFrame(self.refit["parameters"])

    @property
    def payload_mass(self) -> float:
        """kg: the tool plate the gravity torques assumed."""
        return float(self.settings["payload_mass_kg"])

    @property
    def payload_com(self) -> tuple[float, float, float]:
        """(3,) m: the tool plate's centre of mass in the flange frame."""
        return tuple(float(v) for v in self.settings["payload_com_m"])

    @property
    def harmonic_orders(self) -> int:
        """K of the joint_harmonics block the loop offered (orders 1..K)."""
        return int(self.settings["harmonic_orders"])

    @property
    def held_zero_offset_std(self) -> float:
        """rad: the controller marks' tolerance on a joint no sensor sees."""
        return float(self.settings["priors"]["std_display_units"]["held_zero_offset_deg"]) * DEG

    @property
    def tool_link_stds(self) -> tuple[float, float, float]:
        """(marker mount m, tool link translation m, tool link rotation rad): the prior stds per axis
        that split the marker's fitted offset between its mount and the flange (`calibration.tool_link`)."""
        stds = self.settings["priors"]["std_display_units"]
        return (
            float(stds["marker_offset_mm"]) * MM,
            float(stds["link_translation_mm"]) * MM,
            float(stds["link_rotation_deg"]) * DEG,
        )

    @property
    def sigma_after(self) -> float:
        """m: the noise std of the selected model."""
        return float(self.sigma_after_mm) * MM

    @property
    def effects_sides(self) -> dict[str, str]:
        """{effect added: 'robot', 'sensor' or 'unattributed'} (`remaster.loop.sides`)."""
        return sides_of(self.effects_added)

    @property
    def closed(self) -> bool | None:
        """The closure test's verdict on the final model: its residual down to the noise floor (None
        where the closure knew no floor)."""
        value = (self.closure or {}).get("closed")
        return None if value is None else bool(value)

    def declared_model_error(self, model: str) -> float | None:
        """The model error per axis (m) a calibration declares: zero where the closure found the
        loop closed (its residual at the sensor's noise: that is the claim), else the structured
        residual it measured beyond the noise floor (pose-grouped cross-validation on the
        optimization set), of the final model ("loop") or of the zero-offset model ("paper"); None
        when the closure knew no noise floor."""
        rounds = (self.closure or {}).get("rounds") or []
        if not rounds:
            return None
        step = rounds[-1 if model == "loop" else 0]
        if step.get("closed") is None or step.get("structured_mm") is None:
            return None
        return 0.0 if step["closed"] else float(step["structured_mm"]) * MM

    def declared_field(self) -> Hyperparameters | None:
        """The loop model's declared model error as a field over the joints: the kernel of its residual
        field (`model_error_share`: the residual GP's, or fitted on what the model left) with the
        declared error per axis (`declared_model_error('loop')`) as its signal std and no noise (an
        `inference.gp.kernels.Hyperparameters`); None where the loop declares none or the kernel was not
        computed (too few configurations to fit it: the error is then drawn independently per
        configuration)."""
        declared = self.declared_model_error("loop")
        share = self.model_error_share or {}
        if not declared or not share.get("computed") or "kernel" not in share:
            return None
        kernel = Hyperparameters.from_report(share["kernel"])
        return Hyperparameters(kernel.lengthscales, declared, 0.0, kernel.at_bounds)

    @property
    def unseen_by_data(self) -> tuple[str, ...]:
        """Parameters the data cannot see at all."""
        return tuple(self.identifiability["dropped"])

    # ----------------------------------------------------------------------- the file

    def to_json(self) -> dict:
        """The content of loop_closure.json: {key: value}, the sequences as lists (`write` turns any
        NumPy value into a plain number)."""
        out = {}
        for f in fields(self):
            value = getattr(self, f.name)
            if f.name in NOT_WRITTEN or (f.name in OPTIONAL and value is None):
                continue
            out[f.name] = list(value) if isinstance(value, tuple) else value
        # for the file's reader: each effect's side (`remaster.loop.sides`), derived, not read back
        out["effects_sides"] = self.effects_sides
        return out

    def write(self, path):
        """Write loop_closure.json (`files.write_json`: sorted keys, same report, same bytes); returns its path."""
        return write_json(path, self.to_json())

    @classmethod
    def of(cls, content: Mapping, source: str = "loop_closure.json") -> LoopReport:
        """From the JSON content; a missing key (or one of the nested keys the properties read) is an
        InputError naming the file and the key."""
        get = report_reader(content, source, "missing in the loop-closure report")
        for path in (
            ("settings", "payload_mass_kg"),
            ("settings", "payload_com_m"),
            ("settings", "harmonic_orders"),
            ("settings", "priors", "std_display_units", "held_zero_offset_deg"),
            ("settings", "priors", "std_display_units", "marker_offset_mm"),
            ("settings", "priors", "std_display_units", "link_translation_mm"),
            ("settings", "priors", "std_display_units", "link_rotation_deg"),
            ("identifiability", "dropped"),
            ("refit", "parameters"),
        ):
            get(*path)
        if not isinstance(get("refit", "parameters"), list):
            raise InputError("not a list of parameters", file=source, key="refit/parameters")
        if not isinstance(get("effects_added"), list):
            raise InputError("not a list of effects", file=source, key="effects_added")
        sequences = ("effects_added", "rounds", "prior_dominated", "warnings", "zero_offset_shifts")
        numbers = ("validation_rmse_before_mm", "validation_rmse_after_mm", "sigma_before_mm", "sigma_after_mm")
        values = {}
        for f in fields(cls):
            if f.name in NOT_WRITTEN or (f.name in OPTIONAL and f.name not in content):
                continue
            value = get(f.name)
            if f.name in numbers:  # NaN is written as null (a campaign without a validation set)
                values[f.name] = float(value) if value is not None else float("nan")
            else:
                values[f.name] = tuple(value) if f.name in sequences else value
        return cls(**values, source=source)

    @classmethod
    def read(cls, path) -> LoopReport:
        """From loop_closure.json; InputError naming the file, and the key when one is missing."""
        return cls.of(read_json(path), source=str(path))


@dataclass(frozen=True, eq=False)
class LoopResults:
    """What the later stages read of one sensor's loop closure: its report, its MCMC refit's samples
    (SI; None or empty when the refit ran without MCMC) and its residual GP's training rows
    (`residual_gp.training_frame`; None or empty when it added none); label: the samples' file, for
    error messages."""

    report: LoopReport
    samples: pd.DataFrame | None = None
    gp_rows: pd.DataFrame | None = None
    label: str = ""
