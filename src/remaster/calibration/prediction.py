"""Calibrations as predictions: robot-frame marker positions of a campaign's calibrated kinematics
at any joint readings (docs/methods.md, "Across campaigns": predictions, not parameters, are what
campaigns share; `remaster.comparing.predictions` compares two of them).

A `Calibration` is one campaign's (and sensor's) kinematics under one model:

- `nominal`: zero corrections, the nominal chain;
- `paper`: the paper's model, its posterior-mean zero-offsets (held ones at their held value);
- `loop`: the loop closure's model, the posterior means of every parameter of the effects it added
  (zero-offsets, link geometry, joint compliance with gravity torques at the readings predicted,
  joint scale, marker offset).

Only what belongs to the robot (and its marker) is carried: the registration, the sensor scale and
the sensor frame's distortion belong to one campaign's sensor set-up and the drift to one campaign's clock or temperature, so
they are left out (`SETUP_BLOCKS`); a calibration applied elsewhere gets that campaign's own
registration, and its marker refitted about the one carried (`comparing.transfer`).

SI inside (m, rad).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import NamedTuple

import numpy as np
import pandas as pd

from .. import identity, seeding
from ..campaigns.campaign import Campaign, SensorData
from ..errors import InputError, require_columns
from ..inference import metrics
from ..inference.blocks import BlockModel
from ..inference.laplace_report import LaplaceReport
from ..inference.parameter_blocks import EXTENSIONS, carried_by_marker_offset, link_errors
from ..inference.readings import ModelSettings, Readings
from ..loop.result import LoopReport
from ..robot import priors
from ..robot.gravity import loaded_torques
from ..robot.kinematics import ForwardKinematics, KinematicChain, perturbed_chain

DEFAULT_SETTINGS = ModelSettings()  # frozen: one instance serves every default

MODELS = ("nominal", "paper", "loop")
ZERO_OFFSET_PREFIX = "zero_offsets.q"
# one campaign's set-up: never transferred (the sensor's frame distortion is its sensor's, like its scale)
SETUP_BLOCKS = ("registration", "sensor_scale", "drift", "noise", "sensor_distortion")
ESTIMATED = "estimated"
DEFAULT_MARKER_STD = priors.DEFAULTS[priors.DEFAULTS[priors.CLASS_KEY]]["marker_offset_mm"] * priors.MM


@dataclass(frozen=True, eq=False)
class Calibration:
    """One model's calibrated kinematics of one campaign and sensor.

    model: 'nominal', 'paper' or 'loop'; values: {parameter name: SI value} of every parameter
    (held ones at their held value); blocks: the extension blocks of the model (`parameter_blocks.EXTENSIONS`
    names, set-up blocks dropped); settings: payload for the gravity torques; draws: posterior
    samples (m, P) of its free parameters (SI, columns = names), None or empty without them;
    unseen_std: {held zero-offset: std rad} of the joints these data did not see, which a sensor
    registered anew would (none a registration absorbs): drawn at the controller marks' tolerance
    about their held value with the posterior's draws, but for those in `carried`, which the model's
    fitted marker offset carries at the marker (drawn again once the marker offset is left out).
    """

    model: str
    values: Mapping[str, float] = field(default_factory=dict)
    blocks: tuple[str, ...] = ()
    settings: ModelSettings = DEFAULT_SETTINGS
    draws: pd.DataFrame | None = None
    unseen_std: Mapping[str, float] = field(default_factory=dict)
    carried: frozenset[str] = frozenset()

    @property
    def drawn_unseen(self) -> dict[str, float]:
        """{held zero-offset: std rad} that `draw_values` draws: `unseen_std` but for `carried`."""
        return {n: s for n, s in self.unseen_std.items() if n not in self.carried}

    @property
    def effects(self) -> str:
        """The blocks as text, 'none' for the paper's model: 'link_geometry + joint_compliance'."""
        return " + ".join(self.blocks) or "none"

    @property
    def linear_joints(self) -> tuple[int, ...]:
        """The joints (indices) this model corrects in proportion to their reading (`joint_scale`,
        s_j q_j, estimated or held away from 0): not periodic in them, so a reading one turn from
        the measured ones is not the configuration measured (`robot.nearness`)."""
        if "joint_scale" not in self.blocks:
            return ()
        free = set() if self.draws is None else set(self.draws.columns)
        names = [n for n in self.values if n.startswith("joint_scale.q")]
        return tuple(
            sorted(int(n.removeprefix("joint_scale.q")) - 1 for n in names if n in free or self.values[n] != 0.0)
        )

    def predictor(self, chain: KinematicChain, q, marker) -> Predictor:
        return Predictor(chain, q, marker, self.blocks, self.settings)

    def draw_values(self, count: int, rng: np.random.Generator) -> list[dict[str, float]] | None:
        """`count` posterior draws (rows chosen by rng, with replacement only when there are fewer
        rows), held parameters at their values; None without samples."""
        if self.draws is None or self.draws.empty:
            return None
        rows = rng.choice(len(self.draws), count, replace=len(self.draws) < count)
        free = self.draws.iloc[rows].to_dict(orient="records")
        unseen = self.drawn_unseen
        if unseen:  # drawn only where there are some: the other calibrations' draws stay as they were
            names = sorted(unseen)
            shifts = rng.standard_normal((count, len(names))) * np.array([unseen[n] for n in names])
            free = [
                {**row, **{n: self.values[n] + d for n, d in zip(names, shift)}} for row, shift in zip(free, shifts)
            ]
        return [{**self.values, **row} for row in free]


class Predictor:
    """Robot-frame marker positions at fixed readings q (n, N) rad for any parameter values of a
    model with extension `blocks` (set-up blocks ignored). marker (3,) m nominal, flange frame;
    gravity torques (payload from `settings`) are computed once at q, so a compliance acts as at
    those readings; nothing is measured there (measured positions are zeros)."""

    def __init__(
        self, chain: KinematicChain, q, marker, blocks: Sequence[str] = (), settings: ModelSettings = DEFAULT_SETTINGS
    ):
        q = np.atleast_2d(np.asarray(q, dtype=float))
        kept = tuple(b for b in EXTENSIONS if b in blocks and b not in SETUP_BLOCKS)
        links = None
        if "joint_compliance" in kept:  # the torques the fit's readings had: a URDF's own tool counted once
            loaded = loaded_torques(chain, q, settings.payload_mass, settings.payload_com)
            torques, payload, links = loaded.torques, loaded.payload_torques, loaded.body_torques
        else:
            torques = payload = np.zeros_like(q)
        data = Readings(
            np.arange(len(q)),
            q,
            np.zeros((len(q), 3)),
            torques,
            payload,
            harmonic_orders=settings.harmonic_orders,
            body_torques=links,
        )
        self.model = BlockModel(chain, data, marker, np.eye(4), kept)

    def points(self, values: Mapping[str, float]) -> np.ndarray:
        """Marker positions (n, 3) m in the robot frame; parameters not in `values` are 0 (nominal)."""
        return self.model.robot_points(self._vector(values))

    def points_of_draws(self, draws: Sequence[Mapping[str, float]]) -> np.ndarray:
        """Marker positions (m, n, 3) m in the robot frame for m parameter sets (`points` each)."""
        return self.model.robot_points(np.array([self._vector(values) for values in draws]))

    def flange_poses(self, values: Mapping[str, float]) -> np.ndarray:
        """Flange poses (n, 4, 4) in the robot frame: the joint angles the joint-space effects give
        and the links the link geometry gives (the marker offset is not the flange's)."""
        model = self.model
        chain = (
            perturbed_chain(model.chain, link_errors(model.chain, values))
            if "link_geometry" in model.blocks
            else model.chain
        )
        return ForwardKinematics(chain, model.angles(self._vector(values))).flange_poses()

    def _vector(self, values: Mapping[str, float]) -> np.ndarray:
        return np.array([float(values.get(name, 0.0)) for name in self.model.all_names])


def robot_points(
    chain: KinematicChain,
    q,
    marker,
    values: Mapping[str, float],
    blocks: Sequence[str] = (),
    settings: ModelSettings = DEFAULT_SETTINGS,
) -> np.ndarray:
    """Marker positions (n, 3) m in the robot frame at readings q (n, N) rad for parameter values
    {name: SI} of the base + `blocks` model (see `Predictor`)."""
    return Predictor(chain, q, marker, blocks, settings).points(values)


# --------------------------------------------------------------------------- calibrations from results


def _free_draws(samples: pd.DataFrame | None, names: Sequence[str], label: str) -> pd.DataFrame | None:
    """The samples' columns of the free parameters `names` (SI), None when there are no samples."""
    if samples is None or samples.empty:
        return None
    require_columns(samples, names, file=label, of="the posterior samples")
    return samples[list(names)].astype(float).reset_index(drop=True)


def paper_calibration(summary: pd.DataFrame, samples: pd.DataFrame | None = None, label: str = "") -> Calibration:
    """The paper's model from its posterior summary (`posterior_summary.posterior_summary`: parameter, mean SI,
    status) and, when given, its posterior samples (free parameters' columns)."""
    if "parameter" in summary.columns:
        summary = summary.set_index("parameter")
    require_columns(summary, ("mean", "status"), file=label, of="a posterior summary")
    names = [str(n) for n in summary.index if str(n).startswith(ZERO_OFFSET_PREFIX)]
    if not names:
        raise InputError(f"no {ZERO_OFFSET_PREFIX}N parameters", file=label, key="parameter")
    values = {n: float(summary.at[n, "mean"]) for n in names}
    free = [n for n in names if str(summary.at[n, "status"]) == ESTIMATED]
    return Calibration("paper", values, (), ModelSettings(), _free_draws(samples, free, label))


def loop_calibration(report: LoopReport, samples: pd.DataFrame | None = None, label: str = "") -> Calibration:
    """The loop closure's model from its report (`LoopReport.read`: effects added, payload, the refit's
    parameters: parameter, block, mean SI, status) and, when given, its posterior samples."""
    table = report.parameters
    columns = ("parameter", "block", "mean", "status")
    require_columns(table, columns, file=label or report.source, of="the loop closure's parameters")
    kept = table[~table["block"].isin(SETUP_BLOCKS)]
    values = dict(zip(kept["parameter"].astype(str), kept["mean"].astype(float)))
    free = kept.loc[kept["status"].astype(str) == ESTIMATED, "parameter"].astype(str).tolist()
    model_settings = ModelSettings(
        payload_mass=report.payload_mass, payload_com=report.payload_com, harmonic_orders=report.harmonic_orders
    )
    effects = tuple(b for b in EXTENSIONS if b in report.effects_added and b not in SETUP_BLOCKS)
    return Calibration("loop", values, effects, model_settings, _free_draws(samples, free, label))


class Calibrated(NamedTuple):
    """One campaign's sensor with its calibrations. robot: `identity.robot_identity`; date: ISO
    text; models: {model name: Calibration}; excluded: table rows the fit left out as gross errors;
    marker_std: the prior std (m per axis) of the marker's position on the flange, what a transfer to
    this campaign refits it within (the loop closure's prior, else the default class's); loop_closed:
    the loop closure's verdict (`LoopReport.closed`; None: not known)."""

    campaign: str
    date: str
    robot: str
    sensor: SensorData
    chain: KinematicChain
    models: Mapping[str, Calibration]
    excluded: tuple[int, ...] = ()
    marker_std: float = DEFAULT_MARKER_STD
    loop_closed: bool | None = None

    @property
    def kind(self) -> str:
        return self.sensor.kind


def calibrated(
    campaign: Campaign,
    sensor: str,
    summary: pd.DataFrame,
    laplace: LaplaceReport,
    loop: LoopReport | None = None,
    paper_samples: pd.DataFrame | None = None,
    loop_samples: pd.DataFrame | None = None,
) -> Calibrated:
    """A campaign's sensor with its three calibrations, from its fit summary (summary.csv), Laplace
    report (its outlier rows) and loop-closure report (`LoopReport.read`; no loop model without it)."""
    label = f"{campaign.name}/{sensor}"
    if sensor not in campaign.sensors:
        raise InputError(f"no sensor {sensor!r} in the campaign", file=campaign.name, key="sensors")
    models = {"nominal": Calibration("nominal"), "paper": paper_calibration(summary, paper_samples, label)}
    if loop is not None:
        models["loop"] = loop_calibration(loop, loop_samples, label)
        models = {
            name: with_unseen(c, campaign.chain, laplace, loop.held_zero_offset_std) for name, c in models.items()
        }
    excluded = laplace.outlier_rows
    marker_std = (
        DEFAULT_MARKER_STD
        if loop is None
        else float(loop.settings["priors"]["std_display_units"]["marker_offset_mm"]) * priors.MM
    )
    return Calibrated(
        campaign.name,
        campaign.date.isoformat(),
        identity.robot_identity(campaign),
        campaign.sensors[sensor],
        campaign.chain,
        models,
        excluded,
        marker_std,
        None if loop is None else loop.closed,
    )


def with_unseen(
    calibration: Calibration, chain: KinematicChain, laplace: LaplaceReport, tolerance: float
) -> Calibration:
    """The calibration with the held zero-offsets its data did not see drawn at `tolerance` (rad) in
    its draws (`Calibration.unseen_std`): those no registration absorbs, and at the marker not the
    last joint's where a fitted marker offset carries it (`Calibration.carried`;
    `CalibratedRobot.held_drawn`'s rule for a sensor frame). Unchanged without draws."""
    if calibration.draws is None or calibration.draws.empty:
        return calibration
    held = laplace.held_zero_offsets
    names = [n for n in held if n in calibration.values and n not in laplace.absorbed_by_registration]
    if not names:
        return calibration
    carried = carried_by_marker_offset(chain.n_joints, names, calibration.draws.columns)
    return replace(calibration, unseen_std={n: tolerance for n in names}, carried=carried)


@dataclass(frozen=True)
class Propagation:
    """How a posterior is carried to configurations nobody measured: `draws` posterior draws (pairs
    of draws where two calibrations are compared) at `random_configurations` configurations of the
    robot, drawn from `seed` and its identity (`robot_configurations`)."""

    draws: int = 2000
    random_configurations: int = 1000
    seed: int = 0


def robot_configurations(chain: KinematicChain, robot: str, n: int, seed: int) -> np.ndarray:
    """The one fixed set of random configurations (n, N) rad of a robot: uniform within the joint
    limits, from the generator of (seed, 'comparison', robot slug)."""
    return metrics.random_configurations(chain, n, seeding.generator(seed, "comparison", identity.robot_slug(robot)))


def calibrated_entries(
    campaigns: Mapping[str, Campaign],
    summaries: Mapping[tuple[str, str], pd.DataFrame],
    laplaces: Mapping[tuple[str, str], LaplaceReport],
    loops: Mapping[tuple[str, str], LoopReport] | None = None,
    paper_samples: Mapping[tuple[str, str], pd.DataFrame] | None = None,
    loop_samples: Mapping[tuple[str, str], pd.DataFrame] | None = None,
) -> list[Calibrated]:
    """`calibrated` for every (campaign, sensor) of `summaries`: campaigns {name: Campaign}, the
    others {(campaign, sensor): its summary.csv, Laplace report (`LaplaceReport.read`), loop report (`LoopReport.read`),
    samples_default.parquet, loop_closure/samples.parquet} (loops and samples optional)."""
    loops, paper_samples, loop_samples = loops or {}, paper_samples or {}, loop_samples or {}
    out = []
    for (name, sensor), summary in summaries.items():
        if name not in campaigns:
            raise InputError("a fit summary of a campaign that was not given", file=f"{name}/{sensor}")
        if (name, sensor) not in laplaces:
            raise InputError("no Laplace report", file=f"{name}/{sensor}", key="laplace.json")
        out.append(
            calibrated(
                campaigns[name],
                sensor,
                summary,
                laplaces[(name, sensor)],
                loops.get((name, sensor)),
                paper_samples.get((name, sensor)),
                loop_samples.get((name, sensor)),
            )
        )
    return out
