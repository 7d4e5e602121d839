"""Calibrations as predictions: robot-frame marker positions of a campaign's calibrated kinematics
at any joint readings, and two calibrations compared by what they predict (docs/methods.md, "Across
campaigns": predictions, not parameters, are what campaigns share).

A `Calibration` is one campaign's (and sensor's) kinematics under one model:

- `nominal`: zero corrections, the nominal chain;
- `paper`: the paper's model, its posterior-mean zero-offsets (held ones at their held value);
- `loop`: the loop closure's model, the posterior means of every parameter of the effects it added
  (zero-offsets, link geometry, joint compliance with gravity torques at the readings predicted,
  joint scale, marker offset).

Only what belongs to the robot (and its marker) is carried: the registration, the sensor scale and
the sensor frame's distortion belong to one campaign's sensor set-up and the drift to one campaign's clock or temperature, so
they are left out (`SETUP_BLOCKS`); a calibration applied elsewhere gets that campaign's own
registration.

Two calibrations A and B are compared at one fixed set of configurations q (n, N) by
d(q) = |p_B(q) - p_A(q)|, both at their posterior means: `mean_mm`, `p95_mm` over q. Its null
distribution (no change, only posterior uncertainty) comes from draw pairs k = 1..K: the
deviations e_k(q) = [p_B(draw_B,k)(q) - p_B(mean_B)(q)] - [p_A(draw_A,k)(q) - p_A(mean_A)(q)],
whose mean |e_k| over q is the statistic under no change. `null_p95_of_mean_mm` is its 95th
percentile over the K pairs and the pair is `flagged` when the observed mean exceeds it (a one-sided
test at 5 %: the change of prediction is larger than the two posteriors' own spread explains).
Without posterior samples on one side (MCMC off) there is no null: NaN and not flagged.

SI inside (m, rad); the tables are in mm.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np
import pandas as pd

from .. import seeding
from ..campaigns.campaign import Campaign, SensorData
from ..errors import InputError, require_columns
from ..inference import metrics
from ..inference.blocks import EXTENSIONS, BlockModel, ModelSettings, Readings, block_parameters, link_errors
from ..inference.fit import LaplaceReport
from ..loop.report import LoopReport
from ..robot.gravity import loaded_torques
from ..robot.kinematics import ForwardKinematics, KinematicChain, perturbed_chain
from ..units import MM
from . import comparison

DEFAULT_SETTINGS = ModelSettings()  # frozen: one instance serves every default

MODELS = ("nominal", "paper", "loop")
# one campaign's set-up: never transferred (the sensor's frame distortion is its sensor's, like its scale)
SETUP_BLOCKS = ("registration", "sensor_scale", "drift", "noise", "sensor_distortion")
ESTIMATED = "estimated"
NULL_QUANTILE = 0.95
PREDICTION_COLUMNS = ["count", "mean_mm", "p95_mm", "draw_pairs", "null_p95_of_mean_mm", "flagged", "status"]
DRIFT_COLUMNS = [
    "robot",
    "kind",
    "model",
    "campaign_a",
    "date_a",
    "sensor_a",
    "campaign_b",
    "date_b",
    "sensor_b",
    "effects_a",
    "effects_b",
] + PREDICTION_COLUMNS
AGREEMENT_COLUMNS = [
    "campaign",
    "date",
    "robot",
    "model",
    "sensor_a",
    "sensor_b",
    "effects_a",
    "effects_b",
] + PREDICTION_COLUMNS


@dataclass(frozen=True, eq=False)
class Calibration:
    """One model's calibrated kinematics of one campaign and sensor.

    model: 'nominal', 'paper' or 'loop'; values: {parameter name: SI value} of every parameter
    (held ones at their held value); blocks: the extension blocks of the model (`blocks.EXTENSIONS`
    names, set-up blocks dropped); settings: payload for the gravity torques; draws: posterior
    samples (m, P) of its free parameters (SI, columns = names), None or empty without them.
    """

    model: str
    values: Mapping[str, float] = field(default_factory=dict)
    blocks: tuple[str, ...] = ()
    settings: ModelSettings = DEFAULT_SETTINGS
    draws: pd.DataFrame | None = None

    @property
    def effects(self) -> str:
        """The blocks as text, 'none' for the paper's model: 'link_geometry + joint_compliance'."""
        return " + ".join(self.blocks) or "none"

    def predictor(self, chain: KinematicChain, q, marker) -> Predictor:
        return Predictor(chain, q, marker, self.blocks, self.settings)

    def draw_values(self, count: int, rng: np.random.Generator) -> list[dict[str, float]] | None:
        """`count` posterior draws (rows chosen by rng, with replacement only when there are fewer
        rows), held parameters at their values; None without samples."""
        if self.draws is None or self.draws.empty:
            return None
        rows = rng.choice(len(self.draws), count, replace=len(self.draws) < count)
        free = self.draws.iloc[rows]
        return [{**self.values, **row} for row in free.to_dict(orient="records")]


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
        if "joint_compliance" in kept:  # the torques the fit's readings had: a URDF's own tool counted once
            loaded = loaded_torques(chain, q, settings.payload_mass, settings.payload_com)
            torques, payload = loaded.torques, loaded.payload_torques
        else:
            torques = payload = np.zeros_like(q)
        data = Readings(
            np.arange(len(q)), q, np.zeros((len(q), 3)), torques, payload, harmonic_orders=settings.harmonic_orders
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
    """The paper's model from its posterior summary (`fit.posterior_summary`: parameter, mean SI,
    status) and, when given, its posterior samples (free parameters' columns)."""
    if "parameter" in summary.columns:
        summary = summary.set_index("parameter")
    require_columns(summary, ("mean", "status"), file=label, of="a posterior summary")
    names = [str(n) for n in summary.index if str(n).startswith(comparison.ZERO_OFFSET_PREFIX)]
    if not names:
        raise InputError(f"no {comparison.ZERO_OFFSET_PREFIX}N parameters", file=label, key="parameter")
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
    """One campaign's sensor with its calibrations. robot: `comparison.robot_identity`; date: ISO
    text; models: {model name: Calibration}; excluded: table rows the fit left out as gross errors."""

    campaign: str
    date: str
    robot: str
    sensor: SensorData
    chain: KinematicChain
    models: Mapping[str, Calibration]
    excluded: tuple[int, ...] = ()

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
    excluded = laplace.outlier_rows
    return Calibrated(
        campaign.name,
        campaign.date.isoformat(),
        comparison.robot_identity(campaign),
        campaign.sensors[sensor],
        campaign.chain,
        models,
        excluded,
    )


# --------------------------------------------------------------------------- comparison by prediction


def compare_predictions(
    chain: KinematicChain, q, marker, a: Calibration, b: Calibration, draw_pairs: int, rng: np.random.Generator
) -> dict:
    """What B predicts against what A predicts at configurations q (n, N) rad, marker (3,) m
    (flange frame, each model's marker offset added): count (the configurations), mean_mm and p95_mm of
    |p_B - p_A| at the posterior means, draw_pairs and null_p95_of_mean_mm from `draw_pairs`
    posterior draw pairs (rng chooses the draws), flagged (see the module docstring)."""
    pa, pb = a.predictor(chain, q, marker), b.predictor(chain, q, marker)
    mean_a, mean_b = pa.points(a.values), pb.points(b.values)
    distance = np.linalg.norm(mean_b - mean_a, axis=1)
    row = {
        **metrics.in_mm(metrics.error_summary(distance, ("mean", "p95"))),
        "draw_pairs": 0,
        "null_p95_of_mean_mm": np.nan,
        "flagged": False,
    }
    draws_a, draws_b = a.draw_values(draw_pairs, rng), b.draw_values(draw_pairs, rng)
    if draws_a is None or draws_b is None:
        missing = " and ".join(s for s, d in (("A", draws_a), ("B", draws_b)) if d is None)
        return {**row, "status": f"no null: no posterior samples of {missing}"}
    null = np.array(
        [
            np.linalg.norm((pb.points(db) - mean_b) - (pa.points(da) - mean_a), axis=1).mean()
            for da, db in zip(draws_a, draws_b)
        ]
    )
    threshold = float(np.quantile(null, NULL_QUANTILE))
    flagged = bool(distance.mean() > threshold)
    return {
        **row,
        "draw_pairs": int(len(null)),
        "null_p95_of_mean_mm": threshold / MM,
        "flagged": flagged,
        "status": "compared",
    }


def _entries_frame(entries: Sequence[Calibrated]) -> pd.DataFrame:
    """The entries as over-time rows (campaign, date, robot, sensor, kind, entry index), so that
    `comparison`'s pairing of consecutive campaigns and of a campaign's sensors applies."""
    seen = set()
    for e in entries:
        if (e.campaign, e.sensor.name) in seen:
            raise InputError("given twice", file=f"{e.campaign}/{e.sensor.name}")
        seen.add((e.campaign, e.sensor.name))
    return pd.DataFrame(
        {
            "campaign": [e.campaign for e in entries],
            "date": [e.date for e in entries],
            "robot": [e.robot for e in entries],
            "sensor": [e.sensor.name for e in entries],
            "kind": [e.kind for e in entries],
            "entry": np.arange(len(entries)),
        }
    )


def robot_configurations(chain: KinematicChain, robot: str, n: int, seed: int) -> np.ndarray:
    """The one fixed set of random configurations (n, N) rad of a robot: uniform within the joint
    limits, from the generator of (seed, 'comparison', robot slug)."""
    return metrics.random_configurations(chain, n, seeding.generator(seed, "comparison", comparison.robot_slug(robot)))


def _pair_rows(a: Calibrated, b: Calibrated, q, marker, draw_pairs: int, seed: int, labels: dict) -> list[dict]:
    """One row per model both entries have: labels, effects and `compare_predictions`; the draws of
    each pair and model come from their own generator, so a row does not depend on the others."""
    rows = []
    for model in [m for m in MODELS if m in a.models and m in b.models and m != "nominal"]:
        ca, cb = a.models[model], b.models[model]
        rng = seeding.generator(
            seed,
            "comparison",
            comparison.robot_slug(a.robot),
            a.campaign,
            a.sensor.name,
            b.campaign,
            b.sensor.name,
            model,
        )
        rows.append(
            {
                **labels,
                "model": model,
                "effects_a": ca.effects,
                "effects_b": cb.effects,
                **compare_predictions(a.chain, q, marker, ca, cb, draw_pairs, rng),
            }
        )
    return rows


def _table(rows: list[dict], columns: list[str]) -> pd.DataFrame:
    return pd.DataFrame(rows, columns=columns) if rows else pd.DataFrame(columns=columns)


def prediction_drift(
    entries: Iterable[Calibrated], n_configurations: int = 1000, seed: int = 0, draw_pairs: int = 200
) -> pd.DataFrame:
    """Drift between consecutive campaigns of one robot and sensor kind (pairs as
    `comparison.drift_between` makes them) as the change of predicted marker position, robot
    frame, at the robot's fixed random configurations (`robot_configurations`), per model (paper,
    loop). The marker is campaign A's sensor's nominal one (each model's marker offset added).
    Columns DRIFT_COLUMNS (mm)."""
    entries = list(entries)
    frame = _entries_frame(entries)
    rows, configurations = [], {}
    for robot, kind, a_rows, b_rows in comparison.consecutive_pairs(frame):
        a, b = entries[int(a_rows["entry"].iloc[0])], entries[int(b_rows["entry"].iloc[0])]
        if robot not in configurations:
            configurations[robot] = robot_configurations(a.chain, robot, n_configurations, seed)
        labels = {
            "robot": robot,
            "kind": kind,
            "campaign_a": a.campaign,
            "date_a": a.date,
            "sensor_a": a.sensor.name,
            "campaign_b": b.campaign,
            "date_b": b.date,
            "sensor_b": b.sensor.name,
        }
        rows += _pair_rows(a, b, configurations[robot], a.sensor.marker, draw_pairs, seed, labels)
    return _table(rows, DRIFT_COLUMNS)


def prediction_agreement(
    entries: Iterable[Calibrated], n_configurations: int = 1000, seed: int = 0, draw_pairs: int = 200
) -> pd.DataFrame:
    """The sensors' agreement within each campaign (pairs as `comparison.sensor_agreement` makes
    them) as the difference of predicted positions, robot frame, at the robot's fixed random
    configurations, per model. The point is the midpoint of the two sensors' nominal markers,
    and the marker offsets are left out: each sensor has its own marker, and the comparison is of
    the robot. Columns AGREEMENT_COLUMNS (mm)."""
    entries = list(entries)
    frame = _entries_frame(entries)
    rows, configurations = [], {}
    for a_rows, b_rows in comparison.sensor_pairs(frame):
        a, b = entries[int(a_rows["entry"].iloc[0])], entries[int(b_rows["entry"].iloc[0])]
        if a.robot not in configurations:
            configurations[a.robot] = robot_configurations(a.chain, a.robot, n_configurations, seed)
        a, b = _without_marker_offset(a), _without_marker_offset(b)
        labels = {
            "campaign": a.campaign,
            "date": a.date,
            "robot": a.robot,
            "sensor_a": a.sensor.name,
            "sensor_b": b.sensor.name,
        }
        marker = (np.asarray(a.sensor.marker) + np.asarray(b.sensor.marker)) / 2.0
        rows += _pair_rows(a, b, configurations[a.robot], marker, draw_pairs, seed, labels)
    return _table(rows, AGREEMENT_COLUMNS)


def _without_marker_offset(entry: Calibrated) -> Calibrated:
    """The entry with its models' marker offsets left out (values, blocks and draws)."""
    names = set(block_parameters("marker_offset", entry.chain).names)

    def strip(c: Calibration) -> Calibration:
        if "marker_offset" not in c.blocks:
            return c
        draws = None if c.draws is None else c.draws.drop(columns=[n for n in names if n in c.draws.columns])
        return Calibration(
            c.model,
            {k: v for k, v in c.values.items() if k not in names},
            tuple(b for b in c.blocks if b != "marker_offset"),
            c.settings,
            draws,
        )

    return entry._replace(models={m: strip(c) for m, c in entry.models.items()})


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


PREDICTION_TABLES = {"prediction_drift": prediction_drift, "prediction_agreement": prediction_agreement}


def prediction_table(
    name: str,
    campaigns,
    summaries,
    laplaces,
    loops=None,
    paper_samples=None,
    loop_samples=None,
    n_configurations: int = 1000,
    seed: int = 0,
    draw_pairs: int = 200,
) -> pd.DataFrame:
    """One of PREDICTION_TABLES by name, of the campaigns' calibrations (arguments as
    `calibrated_entries`)."""
    if name not in PREDICTION_TABLES:
        raise ValueError(f"unknown prediction table {name!r}; tables: {sorted(PREDICTION_TABLES)}")
    entries = calibrated_entries(campaigns, summaries, laplaces, loops, paper_samples, loop_samples)
    return PREDICTION_TABLES[name](entries, n_configurations, seed, draw_pairs)


CAPTIONS = {  # the tables' and figures' captions, beside `tables.CAPTIONS`
    "transfer": "Transfer between campaigns of one robot: each campaign's calibration (nominal, paper, loop) on "
    "each campaign's validation set of the same sensor, registration refitted on that campaign's "
    "optimization set with the calibration's kinematics frozen (registration, sensor scale and drift "
    "not transferred); the diagonal is the ordinary validation.",
    "transfer_nominal": "Transfer heat-map, nominal kinematics: validation RMSE (mm), calibrated on (rows) against "
    "evaluated on (columns)",
    "transfer_paper": "Transfer heat-map, the paper's model: validation RMSE (mm), calibrated on (rows) against "
    "evaluated on (columns)",
    "transfer_loop": "Transfer heat-map, the loop closure's model: validation RMSE (mm), calibrated on (rows) "
    "against evaluated on (columns)",
    "prediction_drift": "Drift between consecutive campaigns of one robot and sensor kind as the change of "
    "predicted marker position (robot frame, mm) over one fixed set of random configurations; "
    "flagged where the mean change exceeds the 95th percentile of its posterior null.",
    "prediction_agreement": "Agreement of the sensors of each campaign as the difference of predicted positions "
    "(robot frame, mm) over the robot's random configurations; flagged as for the drift.",
}
