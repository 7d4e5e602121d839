"""`calibrate`: one sensor of a campaign through the pipeline's stages in-process, as one result.

The stages are the workflow's own functions, in its order: the registration and the zero-offset
(paper) model's Laplace fit (`inference.fit`), the loop closure (`loop.loop_closure`), the workspace
claims (`evaluation.workspace`) and the acceptance test on the validation set
(`evaluation.acceptance`). What the workflow adds besides (the paper model's MCMC samplers, the
tables, figures and certificate) is not run: the paper model is its Laplace mode
(`posterior_summary.mode_summary`), as where no sampler ran.
"""

from __future__ import annotations

import json
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
import pandas as pd

from .. import configuration, files, identity, seeding
from ..calibration import compensation, exports, prediction
from ..campaigns import folders
from ..campaigns.campaign import Campaign
from ..errors import InputError
from ..evaluation import acceptance, workspace
from ..inference import fit
from ..inference.laplace_report import LaplaceReport
from ..inference.posterior_summary import mode_summary
from ..loop import loop_closure
from ..loop import settings as loop_settings
from ..loop.result import LoopReport, LoopResults

STAGES = ("loop_closure", "workspace", "acceptance")  # the stages that draw random numbers


@dataclass(frozen=True, eq=False)
class Calibration:
    """One sensor's calibration of a campaign (`calibrate`).

    campaign, sensor: what was calibrated; settings: the full configuration it ran with
    (`configuration.settings`); registration: the sensor's initial registration (t_nr (4, 4), m);
    laplace: the zero-offset (paper) model's Laplace fit; summary: its posterior summary at the
    mode (`posterior_summary.mode_summary`: one row per parameter, mean and std in SI and display units, status);
    loop: the loop closure's report (as loop_closure.json holds it), its MCMC refit's samples (SI;
    None without MCMC) and its residual GP's training rows; workspace: the workspace claims
    (`workspace.WorkspaceAccuracy`: `claims` in mm, one row per model, configurations, frame and
    noise); acceptance: the validation set's acceptance test (its `verdict`: 'pass', 'fail' or
    'not tested')."""

    campaign: Campaign
    sensor: str
    settings: Mapping[str, Any]
    registration: fit.Registration
    laplace: LaplaceReport
    summary: pd.DataFrame
    loop: LoopResults
    workspace: workspace.WorkspaceAccuracy
    acceptance: acceptance.Acceptance

    @property
    def effects(self) -> tuple[str, ...]:
        """The effects the loop closure added to the zero-offset model, in the order added."""
        return tuple(self.loop.report.effects_added)

    @property
    def verdict(self) -> str:
        """The acceptance test's verdict on the loop-closed model: 'pass', 'fail' or 'not tested'."""
        return self.acceptance.verdict

    @property
    def claims(self) -> pd.DataFrame:
        """The workspace claims (`workspace.CLAIM_COLUMNS`, mm)."""
        return self.workspace.claims

    def results(self) -> dict[str, Any]:
        """The results by the keys the workflow's files have (`results.sensor_results`), as the
        command line reads them: registration, laplace, summary (a `parameter` column), paper_samples
        (None: the Laplace approximation), loop, loop_samples, gp."""
        return {
            "registration": self.registration,
            "laplace": self.laplace,
            "summary": self.summary.reset_index(),
            "paper_samples": None,
            "loop": self.loop.report,
            "loop_samples": self.loop.samples,
            "gp": self.loop.gp_rows,
        }

    def corrections(self) -> pd.DataFrame:
        """The loop-closed model's zero-offset corrections as the certificate gives them
        (`exports.controller_offsets`: correction, std, u_between, u_model and U, deg and rad)."""
        return exports.loop_offsets(self.campaign.chain.joint_names, self.loop.report)

    def robot(self, model: str = "loop", tcp=None) -> compensation.CalibratedRobot:
        """The calibrated robot `remaster predict` and `compensate` use: model 'loop' (default) or
        'paper'; tcp (3,) m in the flange frame, or None for the sensor's marker."""
        label = f"{self.campaign.name}/{self.sensor}"
        return compensation.calibrated_robot(self.campaign, self.sensor, model, self.results(), tcp, label)


def as_campaign(campaign: Campaign | str, repo_root=None) -> Campaign:
    """A campaign, or the campaign folder (data/raw/<name>) read and validated (`folders.read_campaign`;
    shared URDFs are looked for under repo_root, default the current directory)."""
    return campaign if isinstance(campaign, Campaign) else folders.read_campaign(campaign, repo_root)


def as_read_back(report: LoopReport) -> LoopReport:
    """The loop closure's report as every later stage reads it from loop_closure.json (the same
    JSON text `LoopReport.write` writes, read back: plain numbers and lists)."""
    return LoopReport.of(json.loads(files.json_text(report.to_json(), report.source)), report.source)


def calibrate(
    campaign: Campaign | str,
    sensor: str,
    settings: Mapping[str, Any] | None = None,
    *,
    seed: int | None = None,
    without: Sequence[str] = (),
) -> Calibration:
    """Calibrate one sensor of a campaign (a `Campaign` or its folder) as the workflow does (module
    docstring), with `settings` (config.yaml's content or any part of it; the schema's defaults for
    the rest, `configuration.settings`). The random streams are the workflow's
    (`seeding.generator` of the settings' seed, the campaign, the sensor and the stage); with
    `seed`, each stage draws from `numpy.random.default_rng(seed)` instead, and the workspace's
    random configurations come from it. `without`: candidate effects the loop closure is not
    offered (e.g. ('joint_harmonics',)). Takes the time of the loop closure (seconds to minutes)."""
    campaign = as_campaign(campaign)
    if sensor not in campaign.sensors:
        raise InputError(
            f"no sensor {sensor!r} in the campaign (known: {', '.join(campaign.sensors)})",
            file=campaign.name,
            key="sensors",
        )
    config = configuration.settings(settings)
    if seed is None:
        streams = {stage: seeding.generator(config["seed"], campaign.name, sensor, stage) for stage in STAGES}
    else:
        streams = {stage: np.random.default_rng(seed) for stage in STAGES}
    accuracy = config["accuracy"]
    propagation = prediction.Propagation(
        accuracy["draws"], accuracy["random_configurations"], config["seed"] if seed is None else seed
    )
    return _stages(campaign, sensor, config, streams.__getitem__, propagation, tuple(without))


def _stages(
    campaign: Campaign,
    sensor: str,
    config: Mapping,
    stream: Callable[[str], np.random.Generator],
    propagation: prediction.Propagation,
    without: tuple[str, ...],
) -> Calibration:
    """The stages of `calibrate` with their random streams (stream(stage)) and the workspace's propagation."""
    registration = fit.registration_stage(campaign, sensor)
    laplace = LaplaceReport.of(fit.laplace_stage(campaign, sensor, registration, config["outliers"]))
    settings = loop_settings.from_config(config)
    settings = replace(settings, candidates=tuple(c for c in settings.candidates if c not in without))
    closed = loop_closure.loop_closure_stage(campaign, sensor, registration, laplace, stream("loop_closure"), settings)
    loop = LoopResults(as_read_back(closed.report), closed.samples, closed.gp)
    summary = mode_summary(laplace)
    data = campaign.sensors[sensor]
    claims = workspace.workspace_accuracy(
        campaign.chain,
        data,
        identity.robot_identity(campaign),
        summary,
        laplace,
        loop,
        stream("workspace"),
        propagation,
    )
    accepted = acceptance.acceptance_stage(
        campaign, sensor, registration.t_nr, laplace, None, loop, stream("acceptance"), config["acceptance"]
    )
    return Calibration(campaign, sensor, config, registration, laplace, summary, loop, claims, accepted)
