"""Accuracy stage: the paper's section Quantifying Positional Accuracy and its Validation, per sensor.

Two remastered robots are compared (the metrics themselves are `remaster.inference.metrics`):

- Vernier: the controller's zero-offsets (every correction Theta2 = 0) with the initial
  three-point registration T_NR (Theta1 = 0), as the paper scored them (its eq. post_reg_accuracy
  with the existing registration). Beside it in the post-registration rows only, "Vernier
  (least-squares registration)": the same zero-offsets with the registration that fits them best,
  i.e. Theta1 refit by least squares with Theta2 = 0 on the measured points of the optimization
  set. T*(Theta1) T_NR ranges over every rigid transform, so this refit is exactly the Kabsch
  registration of the nominal forward kinematics onto the measured points (closed form, no
  iteration); its Theta1 is reported. Three points carry the sensor's and the robot's errors into
  the frame, so the paper's scoring is the larger.
- Bayesian: the MLE, i.e. the posterior means of the free parameters (as in the paper and
  `posterior_summary.posterior_summary`), held parameters at their held value, with its fitted registration
  T*(Theta1_MLE) T_NR.

Per sensor and method: relative and post-registration accuracy on the optimization set;
theoretical accuracy (2000 posterior draws, whole rows of the posterior so that correlations
between parameters are kept) at every optimization configuration (the joint readings are known
even where the marker was not seen), at 1000 random configurations, and of the zero-offsets alone
at those random configurations. Held zero-offsets are held in the draws too, so they contribute
nothing (for the iiwa, joint 1: the registration absorbs it, so no sensor can see it).

Validation: relative and post-registration accuracy on the validation set with the optimization
set's parameters, applied in software to the validation readings (the paper applied the motion-
capture MLE to the controller and measured with both sensors; here each sensor's own MLE is
applied; the bundled campaigns record uncorrected readings in both sets, so both are the same
robot). The sensor has not moved between the sets in these campaigns, so the optimization set's
registration is applied as is (the paper's case). A variant refits the registration on the
validation points with the zero-offsets fixed (Kabsch again): a moved sensor would need it, and it
removes any registration error from the validation number. Relative accuracy needs no registration.

Rows whose marker was not seen, and optimization rows the fit flagged as gross errors (the
Laplace report's outlier rows), are left out of the measured metrics
(the Vernier registration included), counted and listed. The theoretical metrics use every
optimization configuration: the joint readings are valid either way.
Everything inside is SI; the returned tables are in mm (columns say _mm).
"""

from __future__ import annotations

import copy
import functools
import logging
from dataclasses import dataclass, replace
from importlib import resources

import numpy as np
import pandas as pd

from .. import spatial
from ..campaigns.campaign import Campaign, SensorData
from ..errors import InputError
from ..inference import metrics
from ..inference.fit import Registration
from ..inference.laplace_report import LaplaceReport
from ..inference.model import (
    SIGMA,
    by_parameter,
    correction_parameters,
    correction_transforms,
    display_scale,
    display_unit,
    parameter_names,
)
from ..labels import paper_order, sensor_label
from ..robot import registration
from ..robot.kinematics import ForwardKinematics, KinematicChain, flange_rotations
from ..units import shown

log = logging.getLogger(__name__)

METHODS = ("Vernier", "Bayesian")
# Vernier scored as the paper scored it (its three-point registration T_NR, Theta1 = 0) and, beside
# it, with the registration that fits the controller's zero-offsets best (least squares): the
# fairer "before" of a certificate. Only post-registration errors depend on the registration.
VERNIER_LEAST_SQUARES = "Vernier (least-squares registration)"
SCORED_METHODS = ("Vernier", VERNIER_LEAST_SQUARES, "Bayesian")
TABLE_METHODS = SCORED_METHODS + ("Loop-closed",)  # the loop-closed model's rows (`workspace`) follow the paper's
TO_MM = 1e3  # m -> mm, for the returned tables only
MIN_REGISTRATION_POINTS = 3

RELATIVE = "relative"
POST_REGISTRATION = "post_registration"
POST_REGISTRATION_REFIT = "post_registration_refit"
REGISTRATION_NOT_USED = "none: distances are frame-invariant"
REGISTRATION_AS_FITTED = "optimization set's, as is (sensor not moved)"
REGISTRATION_REFIT = "refit on the validation points, zero-offsets fixed"

METRIC_TABLES = (
    "relative_accuracy",
    "post_registration_accuracy",
    "theoretical_accuracy_optimization_configs",
    "theoretical_accuracy_random_configs",
    "theoretical_accuracy_zero_offsets_only",
)
VALIDATION_TABLE = "validation_accuracy"
TABLE_NAMES = METRIC_TABLES + (VALIDATION_TABLE,)
VALIDATION_METRICS = {
    RELATIVE: ("Relative", REGISTRATION_NOT_USED),
    POST_REGISTRATION: ("Post-Registration Absolute", REGISTRATION_AS_FITTED),
    POST_REGISTRATION_REFIT: ("Post-Registration Absolute (registration refit on validation set)", REGISTRATION_REFIT),
}
SUMMARY_COLUMNS = ("mean_mm", "q2.5_mm", "q97.5_mm", "count")
CONFIGURATION_COLUMNS = (
    "set",
    "registration",
    "method",
    "row",
    "pose",
    "solution",
    "configuration",
    "error_mm",
    "residual_x_mm",
    "residual_y_mm",
    "residual_z_mm",
    "distance_from_base_mm",
)


# --------------------------------------------------------------------------- remastered robots


@dataclass(frozen=True, eq=False)
class Remastered:
    """A remastering method's robot: zero-offsets (N,) rad added to the readings and the sensor
    <- robot transform (4, 4) that goes with them (T*(Theta1) T_NR)."""

    method: str
    zero_offsets: np.ndarray
    sensor_from_robot: np.ndarray

    def robot_points(self, chain: KinematicChain, q, marker) -> np.ndarray:
        """Marker positions (n, 3) m in the robot frame at readings q (n, N)."""
        return ForwardKinematics(chain, q).points(marker, self.zero_offsets)

    def registered_to(self, chain: KinematicChain, q, measured, marker) -> Remastered:
        """The same zero-offsets with the least-squares registration onto measured points (n, 3)."""
        return replace(self, sensor_from_robot=registration.kabsch(self.robot_points(chain, q, marker), measured))


def vernier(chain: KinematicChain, t_nr) -> Remastered:
    """Controller zero-offsets (zero corrections) with the initial three-point registration T_NR
    (Theta1 = 0), as the paper scored them."""
    return Remastered("Vernier", np.zeros(chain.n_joints), np.asarray(t_nr, dtype=float))


def vernier_least_squares(chain: KinematicChain, q, measured, marker) -> Remastered:
    """Controller zero-offsets with the registration that fits them best on measured points
    (n, 3) m at readings q (n, N): Theta1 by least squares = Kabsch."""
    controller = Remastered(VERNIER_LEAST_SQUARES, np.zeros(chain.n_joints), np.eye(4))
    return controller.registered_to(chain, q, measured, marker)


def parameter_table(samples: pd.DataFrame, laplace: LaplaceReport, n_joints: int) -> pd.DataFrame:
    """Every model parameter (6 registration + N zero-offsets) and noise.sigma per posterior
    sample, SI: free ones from the samples, held ones at their held value."""
    names = list(laplace.parameters)
    if names != list(parameter_names(n_joints)):
        raise ValueError(f"the fit's parameters {names} are not those of a {n_joints}-joint robot")
    held = laplace.held
    columns = {
        name: (np.full(len(samples), float(held[name])) if name in held else samples[name].to_numpy(float))
        for name in names + [SIGMA]
    }
    return pd.DataFrame(columns)


def bayesian(mle: pd.Series, t_nr) -> Remastered:
    """The MLE's robot from every parameter's MLE (a `parameter_table` row, SI) and the initial T_NR."""
    every = mle.to_numpy(float)
    return Remastered("Bayesian", every[6:-1], correction_transforms(every[:6]) @ np.asarray(t_nr, dtype=float))


def registration_parameters(sensor_from_robot, t_nr) -> np.ndarray:
    """Theta1 (6,) (x, y, z m; alpha, beta, gamma rad) with T*(Theta1) T_NR = sensor_from_robot."""
    return correction_parameters(
        np.asarray(sensor_from_robot, dtype=float) @ spatial.invert(np.asarray(t_nr, dtype=float))
    )


# --------------------------------------------------------------------------- one set's data


@dataclass(frozen=True, eq=False)
class SetData:
    """One set's rows of a sensor table: rows (n,) 0-based table rows, q (n, N) rad, positions
    (n, 3) m in the sensor frame, NaN where the row is not used (marker unseen or flagged),
    poses (n,) and solutions (n,) ints, unseen and flagged (n,) booleans; for a full-pose probe,
    orientations (n, 3, 3) its measured rotations in the sensor frame (NaN where not measured)
    and probe_rotation (3, 3) its nominal rotation in the flange frame, else None."""

    name: str
    rows: np.ndarray
    q: np.ndarray
    positions: np.ndarray
    poses: np.ndarray
    solutions: np.ndarray
    unseen: np.ndarray
    flagged: np.ndarray
    orientations: np.ndarray | None = None
    probe_rotation: np.ndarray | None = None

    @classmethod
    def of(cls, sensor: SensorData, set_name: str, flagged_rows=()) -> SetData:
        """The set's rows; flagged_rows (table rows, e.g. gross errors) are left out like unseen ones."""
        mask = sensor.set_mask(set_name)
        table = sensor.table[mask]
        rows = np.flatnonzero(mask)
        positions = np.array(sensor.positions(set_name), dtype=float)  # a copy: flagged rows become NaN
        unseen = ~np.all(np.isfinite(positions), axis=1)
        flagged = np.isin(rows, np.asarray(flagged_rows, dtype=np.int64)) & ~unseen
        positions[flagged] = np.nan
        return cls(
            set_name,
            rows,
            sensor.q(set_name),
            positions,
            table["pose"].to_numpy(np.int64),
            table["solution"].to_numpy(np.int64),
            unseen,
            flagged,
            sensor.orientations(rows) if sensor.has_orientation else None,
            sensor.probe_rotation,
        )

    @property
    def usable(self) -> np.ndarray:
        """Boolean (n,): the marker was seen and the row not flagged."""
        return ~(self.unseen | self.flagged)

    @property
    def unseen_rows(self) -> list[int]:
        """Table rows of the set whose marker was not seen."""
        return [int(r) for r in self.rows[self.unseen]]

    @property
    def flagged_rows(self) -> list[int]:
        """Table rows of the set left out as flagged (gross errors)."""
        return [int(r) for r in self.rows[self.flagged]]


def _summary_row(values_m, **labels) -> dict:
    """Labels plus mean, 95 % interval (mm) and count of values in m."""
    summary = metrics.error_summary(values_m)
    return {
        **labels,
        "mean_mm": summary["mean"] * TO_MM,
        "q2.5_mm": summary["q2.5"] * TO_MM,
        "q97.5_mm": summary["q97.5"] * TO_MM,
        "count": summary["count"],
    }


def _relative(chain: KinematicChain, data: SetData, robot: Remastered, marker) -> np.ndarray:
    """Relative errors (k,) m within each pose of the set; unused rows skipped."""
    return metrics.relative_errors(data.positions, robot.robot_points(chain, data.q, marker), data.poses)


def _configuration_errors(
    chain: KinematicChain, data: SetData, robot: Remastered | None, marker, registration_label: str
) -> tuple[np.ndarray, pd.DataFrame]:
    """Post-registration errors (n_used,) m and their per-configuration table (mm) for the used
    rows of a set; robot None (no registration possible) gives no rows."""
    seen = np.flatnonzero(data.usable)
    if robot is None or seen.size == 0:
        return np.empty(0), pd.DataFrame(columns=list(CONFIGURATION_COLUMNS))
    q, measured = data.q[seen], data.positions[seen]
    robot_frame = robot.robot_points(chain, q, marker)
    predicted = spatial.transform_points(robot.sensor_from_robot, robot_frame)
    errors = metrics.post_registration_errors(measured, predicted)
    residuals = (measured - predicted) * TO_MM
    frame = pd.DataFrame(
        {
            "set": data.name,
            "registration": registration_label,
            "method": robot.method,
            "row": data.rows[seen],
            "pose": data.poses[seen],
            "solution": data.solutions[seen],
            "configuration": seen,
            "error_mm": errors * TO_MM,
            "residual_x_mm": residuals[:, 0],
            "residual_y_mm": residuals[:, 1],
            "residual_z_mm": residuals[:, 2],
            "distance_from_base_mm": np.linalg.norm(robot_frame, axis=1) * TO_MM,
        }
    )
    if data.orientations is not None:
        frame["orientation_error_deg"] = np.degrees(orientation_errors(chain, data, robot, seen))
    return errors, frame


def orientation_errors(chain: KinematicChain, data: SetData, robot: Remastered, at) -> np.ndarray:
    """A full-pose probe's orientation errors (len(at),) rad at rows `at` of the set: the angle of
    R_measured R_predicted^T, R_predicted the robot's flange at its zero-offsets, turned by its
    registration and the probe's nominal mounting; NaN where the orientation was not measured."""
    flange = flange_rotations(chain, data.q[at] + robot.zero_offsets)
    predicted = robot.sensor_from_robot[:3, :3] @ flange @ data.probe_rotation
    residual = spatial.matrix_to_rotation_vector(data.orientations[at] @ np.swapaxes(predicted, -1, -2))
    return np.linalg.norm(residual, axis=-1)


# --------------------------------------------------------------------------- the stage

# how each method and registration was obtained (the report's notes)
REPORT_NOTES = {
    "vernier": "controller zero-offsets with the initial three-point registration T_NR (the paper's scoring)",
    "vernier_least_squares": "controller zero-offsets; registration by least squares (Kabsch) with "
    "zero-offsets 0 on the optimization set's used points (seen, not flagged); "
    "post-registration errors only",
    "bayesian": "posterior means of the free parameters, held parameters at their held value, with the "
    "fitted registration T*(Theta1) T_NR",
    "theoretical": "distances in the robot frame between the method's TCP and the TCPs of posterior draws "
    "(whole posterior rows), with each draw's N(0, sigma^2 I3) added except for zero-offsets "
    "only; optimization configurations include rows whose marker was not seen; above "
    f"{metrics.THEORETICAL_PAIRS:,} draw x configuration pairs, a systematic sample of them (draw i at the "
    "configurations i mod k, i mod k + k, ...; the count column says how many)",
    "validation_registration": {
        POST_REGISTRATION: REGISTRATION_AS_FITTED,
        POST_REGISTRATION_REFIT: REGISTRATION_REFIT,
    },
}


def _rows_report(optimization: SetData, validation: SetData) -> dict:
    """The report's rows of each set: left out (marker not seen; flagged), with counts, and used;
    and the configuration of the TCP scatter (the first optimization row's)."""
    sets = (optimization, validation)
    first = {
        "row": int(optimization.rows[0]),
        "pose": int(optimization.poses[0]),
        "solution": int(optimization.solutions[0]),
    }
    return {
        "tcp_scatter_configuration": first if len(optimization.rows) else None,
        "excluded_rows_marker_not_seen": {data.name: data.unseen_rows for data in sets},
        "excluded_rows_outliers": {data.name: data.flagged_rows for data in sets},
        "excluded_counts": {
            data.name: {"marker_not_seen": len(data.unseen_rows), "outliers": len(data.flagged_rows)} for data in sets
        },
        "configurations": {data.name: int(len(data.rows)) for data in sets},
    }


def _theoretical_tables(chain, optimization_q, random_q, marker, robots, draw_offsets, draw_sigma, rng) -> dict:
    """The paper's theoretical tables, one row per method: the TCP's distance to the posterior
    draws' (zero-offsets (k, N), noise stds (k,) m) at the optimization configurations and at the
    random ones, with each draw's noise, and at the random ones without it (zero-offsets only)."""
    out = {}
    for table, q, sigma in (
        ("theoretical_accuracy_optimization_configs", optimization_q, draw_sigma),
        ("theoretical_accuracy_random_configs", random_q, draw_sigma),
        ("theoretical_accuracy_zero_offsets_only", random_q, None),
    ):
        out[table] = pd.DataFrame(
            [
                _summary_row(
                    metrics.theoretical_errors(chain, q, marker, robot.zero_offsets, draw_offsets, sigma, rng),
                    method=method,
                )
                for method, robot in robots.items()
            ]
        )
    return out


def accuracy_tables(
    campaign: Campaign,
    sensor_name: str,
    registration: Registration,
    laplace: LaplaceReport,
    samples: pd.DataFrame,
    rng: np.random.Generator,
    n_draws: int = 2000,
    n_random: int = 1000,
) -> dict:
    """Every accuracy metric of one sensor, Vernier and Bayesian (see the module docstring).

    registration: `fit.Registration` (its t_nr); laplace: `laplace_report.LaplaceReport`;
    samples: `posterior_sampling.samples_frame` (SI). rng draws the posterior rows, the random configurations and
    the Gaussian errors, in that order. Returns:

    - the metric tables `METRIC_TABLES`: one row per method (Vernier, Bayesian) with method,
      mean_mm, q2.5_mm, q97.5_mm, count (pairs for relative accuracy, configurations for
      post-registration, draws x configurations for theoretical);
    - "validation_accuracy": rows metric (relative, post_registration, post_registration_refit),
      registration (how the sensor frame was obtained), method, mean_mm, q2.5_mm, q97.5_mm, count;
    - "configuration_errors": per used configuration, set, registration and method: set,
      registration, method, row, pose, solution, configuration (index in the set), error_mm,
      residual_{x,y,z}_mm (measured - predicted, sensor frame), distance_from_base_mm (robot frame);
    - "tcp_scatter": fig. accuracy's data at the first optimization configuration, robot frame,
      mm relative to the MLE TCP: kind (Vernier, MLE, probable, probable + noise), x_mm, y_mm, z_mm;
    - "remastering_parameters": per parameter, the values (display units) each method used;
    - "report": JSON-ready: rows left out per set (marker not seen; flagged) with counts, the numbers of
      draws and configurations, and how each method and registration was obtained.
    """
    chain, sensor = campaign.chain, campaign.sensors[sensor_name]
    marker = sensor.marker
    t_nr = registration.t_nr
    parameters = parameter_table(samples, laplace, chain.n_joints)
    mle = parameters.mean()
    optimization = SetData.of(sensor, "optimization", laplace.outlier_rows)
    validation = SetData.of(sensor, "validation")
    used = optimization.usable
    robots = {"Vernier": vernier(chain, t_nr), "Bayesian": bayesian(mle, t_nr)}
    scored = {
        **robots,
        VERNIER_LEAST_SQUARES: vernier_least_squares(chain, optimization.q[used], optimization.positions[used], marker),
    }

    out: dict = {}
    errors = {
        method: _configuration_errors(chain, optimization, robot, marker, REGISTRATION_AS_FITTED)
        for method, robot in scored.items()
    }
    out["relative_accuracy"] = pd.DataFrame(
        [_summary_row(_relative(chain, optimization, robot, marker), method=method) for method, robot in robots.items()]
    )
    out["post_registration_accuracy"] = pd.DataFrame([_summary_row(errors[m][0], method=m) for m in SCORED_METHODS])

    replace_draws = len(parameters) < n_draws
    draws = parameters.iloc[rng.choice(len(parameters), n_draws, replace=replace_draws)]
    draw_offsets = draws[list(parameter_names(chain.n_joints)[6:])].to_numpy()
    draw_sigma = draws[SIGMA].to_numpy()
    random_q = metrics.random_configurations(chain, n_random, rng)
    out.update(_theoretical_tables(chain, optimization.q, random_q, marker, robots, draw_offsets, draw_sigma, rng))

    out.update(_validation_tables(chain, validation, scored, marker, errors))
    out["tcp_scatter"] = tcp_scatter(chain, optimization, marker, robots, draw_offsets, draw_sigma, rng)
    out["remastering_parameters"] = _parameters_used(scored, mle, t_nr, laplace, errors)
    out["report"] = {
        "campaign": campaign.name,
        "sensor": sensor_name,
        **_rows_report(optimization, validation),
        "posterior_samples": int(len(parameters)),
        "draws": int(n_draws),
        "draws_with_replacement": replace_draws,
        "random_configurations": int(n_random),
        "random_configuration_bounds_rad": [b.tolist() for b in metrics.joint_space_bounds(chain)],
        "held_parameters": dict(laplace.held),
        **copy.deepcopy(REPORT_NOTES),
    }
    return out


def _validation_tables(chain: KinematicChain, data: SetData, scored: dict[str, Remastered], marker, errors) -> dict:
    """The validation table (`_validation`) and every configuration's errors: the optimization
    set's (`errors`: {method: (errors, frame)}) then the validation set's."""
    validation_rows, validation_frames = _validation(chain, data, scored, marker)
    frames = [frame for frame in [errors[m][1] for m in SCORED_METHODS] + validation_frames if len(frame)]
    return {
        VALIDATION_TABLE: pd.DataFrame(validation_rows),
        "configuration_errors": (
            pd.concat(frames, ignore_index=True) if frames else pd.DataFrame(columns=list(CONFIGURATION_COLUMNS))
        ),
    }


def _validation(chain: KinematicChain, data: SetData, robots: dict[str, Remastered], marker):
    """(summary rows, per-configuration frames) of the validation set for each method. A
    registration variant of a method (Vernier's least-squares one) gets its post-registration row
    only: its relative accuracy and its refit on the validation points are the method's own."""
    rows, frames = [], []
    seen = np.flatnonzero(data.usable)
    for method, robot in robots.items():
        own = method in METHODS
        if own:
            rows.append(
                _summary_row(
                    _relative(chain, data, robot, marker),
                    metric=RELATIVE,
                    registration=REGISTRATION_NOT_USED,
                    method=method,
                )
            )
        refit = _refit(robot, chain, data, seen, marker)
        for metric, registered, label in (
            (POST_REGISTRATION, robot, REGISTRATION_AS_FITTED),
            (POST_REGISTRATION_REFIT, refit, REGISTRATION_REFIT),
        )[: 2 if own else 1]:
            errors, frame = _configuration_errors(chain, data, registered, marker, label)
            rows.append(_summary_row(errors, metric=metric, registration=label, method=method))
            frames.append(frame)
    order = list(VALIDATION_METRICS)
    rows.sort(key=lambda r: (order.index(r["metric"]), SCORED_METHODS.index(r["method"])))
    return rows, frames


def _refit(robot: Remastered, chain: KinematicChain, data: SetData, seen, marker) -> Remastered | None:
    """The robot with its registration refitted on a set's seen rows; None (no refit rows) with
    fewer than MIN_REGISTRATION_POINTS or points on a line (a set of one or two marker positions:
    a pose's configurations may all put the marker at one point), which fix no rigid transform."""
    if seen.size < MIN_REGISTRATION_POINTS:
        return None
    try:
        return robot.registered_to(chain, data.q[seen], data.positions[seen], marker)
    except InputError as exc:
        log.warning("%s: no registration refit on this set's %d points: %s", robot.method, seen.size, exc)
        return None


def tcp_scatter(
    chain: KinematicChain,
    data: SetData,
    marker,
    robots: dict[str, Remastered],
    draw_offsets,
    draw_sigma,
    rng: np.random.Generator,
) -> pd.DataFrame:
    """Fig. accuracy's points at the set's first configuration, robot frame, mm relative to the
    MLE TCP: kind (Vernier, MLE, probable, probable + noise), x_mm, y_mm, z_mm."""
    if len(data.q) == 0:
        return pd.DataFrame(columns=["kind", "x_mm", "y_mm", "z_mm"])
    q = data.q[:1]
    mle = robots["Bayesian"].robot_points(chain, q, marker)[0]
    probable = metrics.probable_tcps(chain, q, marker, draw_offsets, None, rng)[:, 0]
    noisy = probable + np.asarray(draw_sigma)[:, None] * rng.standard_normal(probable.shape)
    parts = [
        ("probable + noise", noisy),
        ("probable", probable),
        ("MLE", mle[None]),
        ("Vernier", robots["Vernier"].robot_points(chain, q, marker)),
    ]
    frames = [
        pd.DataFrame((points - mle) * TO_MM, columns=["x_mm", "y_mm", "z_mm"]).assign(kind=kind)
        for kind, points in parts
    ]
    return pd.concat(frames, ignore_index=True)[["kind", "x_mm", "y_mm", "z_mm"]]


def _parameters_used(
    robots: dict[str, Remastered], mle: pd.Series, t_nr, laplace: LaplaceReport, errors: dict
) -> pd.DataFrame:
    """Per parameter the value each method used, display units (mm, deg). A Vernier's sigma is the
    ML estimate sqrt(sum ||E_i||^2 / 3n) of its residuals."""
    held = laplace.held
    names = list(mle.index)
    scale = np.array([display_scale(n) for n in names])
    columns = {
        method: np.concatenate(
            [
                registration_parameters(robots[method].sensor_from_robot, t_nr),
                robots[method].zero_offsets,
                [np.sqrt(np.mean(np.square(errors[method][0])) / 3.0)],
            ]
        )
        / scale
        for method in ("Vernier", VERNIER_LEAST_SQUARES)
    }
    return pd.DataFrame(
        {
            "parameter": names,
            "unit": [display_unit(n) for n in names],
            **columns,
            "Bayesian": mle.to_numpy(float) / scale,
            "status": ["held" if n in held else "estimated" for n in names],
        }
    )


# --------------------------------------------------------------------------- paper layout

PAPER_VALUES_FILE = "data/paper_values.csv"  # inside the package: the paper's numbers are data, not code
PAPER_STATISTICS = (("Mean", "mean_mm"), ("2.5%", "q2.5_mm"), ("97.5%", "q97.5_mm"))  # (table label, column)
EMPTY_INTERVAL = "n/a (count 0)"


@functools.cache
def _read_paper_values() -> pd.DataFrame:
    with resources.files("remaster").joinpath(PAPER_VALUES_FILE).open("r", encoding="utf-8") as text:
        return pd.read_csv(text, dtype={"table": str, "source": str, "metric": str, "method": str, "sensor": str})


def paper_values(table_name: str | None = None) -> pd.DataFrame:
    """The paper's published numbers (mm) of the physical NIST experiment that kuka-twin imitates,
    from the package's PAPER_VALUES_FILE (typed from the paper's tables; they are the paper's, not
    ours: only for comparison). One row per table row: table, source (the paper's table label
    `tab:...`), metric (validation table only, else NaN), method, sensor, mean_mm, q2.5_mm, q97.5_mm.
    table_name: only that table's rows; ValueError when the paper has none."""
    values = _read_paper_values()
    if table_name is None:
        return values.copy()
    if table_name not in set(values["table"]):
        raise ValueError(f"no published values for {table_name!r}; tables: {sorted(set(values['table']))}")
    return values[values["table"] == table_name].reset_index(drop=True)


def format_interval(low: float, high: float, count: int) -> str:
    """'[a, b]' (mm, `units.shown`), or EMPTY_INTERVAL when there is no value."""
    return EMPTY_INTERVAL if count == 0 else f"[{shown(low)}, {shown(high)}]"


def _paper_rows(per_sensor: dict[str, pd.DataFrame]) -> pd.DataFrame:
    """Every sensor's metric rows with a sensor column, in the paper's order: (metric, for a
    validation table,) method in TABLE_METHODS order, sensor in the paper's order."""
    sensors = paper_order(per_sensor)
    rows = pd.concat([per_sensor[s].assign(sensor=s) for s in sensors], ignore_index=True)
    validation = "metric" in rows.columns
    metric_order = list(VALIDATION_METRICS)
    order = [
        ((metric_order.index(r["metric"]),) if validation else ())
        + (TABLE_METHODS.index(r["method"]), sensors.index(r["sensor"]))
        for _, r in rows.iterrows()
    ]
    return rows.iloc[sorted(range(len(rows)), key=order.__getitem__)].reset_index(drop=True)


def _row_labels(rows: pd.DataFrame) -> pd.DataFrame:
    """The label columns of a paper table: (Metric,) Remastering Method, Reference Sensor."""
    labels = pd.DataFrame(
        {"Remastering Method": rows["method"].to_numpy(), "Reference Sensor": [sensor_label(s) for s in rows["sensor"]]}
    )
    if "metric" in rows.columns:
        labels.insert(0, "Metric", [VALIDATION_METRICS[m][0] for m in rows["metric"]])
    return labels


def paper_table(per_sensor: dict[str, pd.DataFrame]) -> pd.DataFrame:
    """One metric for every sensor in the paper's layout: rows Vernier, Bayesian (then Loop-closed
    where given, theoretical tables), sensors in
    the paper's order; columns Remastering Method, Reference Sensor, Mean (mm), 95% Interval (mm).
    A validation table (rows with a metric column) gets a leading Metric column, metrics in the
    order relative, post-registration, post-registration with the registration refit.
    per_sensor: sensor -> its metric rows (method, (metric,) mean_mm, q2.5_mm, q97.5_mm, count)."""
    rows = _paper_rows(per_sensor)
    return _row_labels(rows).assign(
        **{
            "Mean (mm)": rows["mean_mm"].to_numpy(float),
            "95% Interval (mm)": [
                format_interval(lo, hi, n) for lo, hi, n in zip(rows["q2.5_mm"], rows["q97.5_mm"], rows["count"])
            ],
        }
    )


def paper_comparison(table_name: str, per_sensor: dict[str, pd.DataFrame]) -> pd.DataFrame:
    """A `paper_table` (same rows, same order) beside the paper's published numbers (`paper_values`;
    meaningful for kuka-twin, the twin of the paper's experiment): for the mean and both interval
    ends, ours, the paper's and ours - paper (mm). Rows the paper has no number for get NaN, and so
    do our interval ends of a row without values (count 0).

    per_sensor: the same {sensor: metric rows} as `paper_table` takes (the numbers, not the
    formatted table): our values are compared unrounded, as computed (not at the 3 decimals the
    table prints). A Note column says, in the tables of PAPER_NOTES, where a row of ours and the
    paper's measure different things."""
    published = paper_values(table_name)
    rows = _paper_rows(per_sensor)
    keys = ["metric", "method", "sensor"] if "metric" in rows.columns else ["method", "sensor"]
    columns = [column for _, column in PAPER_STATISTICS]
    # a left merge keeps our rows and their order; the paper's rows are unique per key
    paper = rows[keys].merge(published[keys + columns], on=keys, how="left", validate="many_to_one")
    has_paper = paper[columns].notna().any(axis=1).to_numpy()
    empty = rows["count"].to_numpy() == 0
    out = _row_labels(rows)
    for statistic, column in PAPER_STATISTICS:
        ours = rows[column].to_numpy(float, copy=True)
        ours[empty] = np.nan
        out[f"{statistic} (mm)"] = ours
        out[f"Paper {statistic} (mm)"] = paper[column].to_numpy(float)
        out[f"{statistic} difference (mm)"] = ours - paper[column].to_numpy(float)
    note = PAPER_NOTES.get(table_name)
    if note is not None:
        methods, text = note
        out["Note"] = [
            text if present and (methods is None or method in methods) else ""
            for present, method in zip(has_paper, rows["method"])
        ]
    return out


_HELD_JOINT_1 = (
    "paper: its posterior draws include a joint-1 zero-offset (table MLE_zero_offsets), which no "
    "registration-free data determine; here joint 1 is held, so this row leaves out that rotation "
    "about base Z"
)
# Why a row of ours and the paper's measure different things: {table: (the methods whose rows the
# paper has a number for it applies to, None for all; note)}
PAPER_NOTES: dict[str, tuple[tuple[str, ...] | None, str]] = {
    VALIDATION_TABLE: (
        None,
        ("paper: motion-capture MLE applied and measured by this sensor; here: this sensor's own MLE"),
    ),
    **{table: (("Vernier",), _HELD_JOINT_1) for table in METRIC_TABLES if table.startswith("theoretical")},
}


# --------------------------------------------------------------------------- sensor comparison


def _accuracy_rows(accuracy) -> pd.DataFrame:
    """Metric rows with a 'quantity' label, from {table name: rows} or a frame with a 'table' column."""
    if isinstance(accuracy, dict):
        accuracy = pd.concat(
            [accuracy[name].assign(table=name) for name in TABLE_NAMES if name in accuracy], ignore_index=True
        )
    labels = []
    for _, row in accuracy.iterrows():
        parts = [row["table"]] + ([row["metric"]] if "metric" in row and isinstance(row["metric"], str) else [])
        labels.append(f"{' / '.join(parts)}: {row['method']}")
    return accuracy.assign(quantity=labels).set_index("quantity")


def sensor_comparison(summaries: dict[str, pd.DataFrame], accuracy: dict) -> pd.DataFrame:
    """The sensors side by side: per parameter each sensor's estimate (posterior mean) and std in
    display units, their difference and that difference in units of the combined uncertainty
    sqrt(std_a^2 + std_b^2); then per accuracy metric each sensor's mean error (mm) and the
    difference (no std: the sensors measure different markers, so it is descriptive).

    summaries: sensor -> `posterior_summary.posterior_summary` (indexed by parameter or with a parameter
    column); accuracy: sensor -> {table name: metric rows} (e.g. `accuracy_tables`' output).
    Columns: kind, quantity, unit, '<Sensor> estimate', '<Sensor> std' per sensor, difference,
    difference / combined std, note. Differences compare the first two sensors in the paper's
    order; registration corrections live in different sensor frames and are marked not
    comparable; with one sensor the table holds its column alone and says so.
    """
    sensors = paper_order(summaries)
    labels = [sensor_label(s) for s in sensors]
    summaries = {s: by_parameter(summaries[s]) for s in sensors}
    accuracy_rows = {s: _accuracy_rows(accuracy[s]) for s in sensors if s in accuracy}
    compared = len(sensors) >= 2
    single_note = f"only one sensor ({labels[0]}): nothing to compare"
    rows = []
    for name in summaries[sensors[0]].index:
        scale = display_scale(name)
        row = {"kind": "parameter", "quantity": name, "unit": display_unit(name)}
        for sensor, label in zip(sensors, labels):
            entry = summaries[sensor].loc[name] if name in summaries[sensor].index else None
            row[f"{label} estimate"] = np.nan if entry is None else float(entry["mean"]) / scale
            row[f"{label} std"] = np.nan if entry is None else float(entry["std"]) / scale
        held = [
            label
            for s, label in zip(sensors, labels)
            if name in summaries[s].index and summaries[s].loc[name, "status"] != "estimated"
        ]
        difference, z, note = np.nan, np.nan, single_note
        if compared:
            a, b = labels[:2]
            if name.startswith("registration."):
                note = "not comparable (different frames)"
            elif held:
                note = f"held at the controller value ({', '.join(held)}): not comparable"
            else:
                difference = row[f"{a} estimate"] - row[f"{b} estimate"]
                z = difference / np.hypot(row[f"{a} std"], row[f"{b} std"])
                note = ""
        rows.append({**row, "difference": difference, "difference / combined std": z, "note": note})
    quantities = next(iter(accuracy_rows.values())).index if accuracy_rows else []
    for quantity in quantities:
        row = {"kind": "accuracy", "quantity": quantity, "unit": "mm"}
        for sensor, label in zip(sensors, labels):
            table = accuracy_rows.get(sensor)
            row[f"{label} estimate"] = (
                float(table.loc[quantity, "mean_mm"]) if table is not None and quantity in table.index else np.nan
            )
            row[f"{label} std"] = np.nan
        difference = row[f"{labels[0]} estimate"] - row[f"{labels[1]} estimate"] if compared else np.nan
        note = "mean error; the sensors measure different markers" if compared else single_note
        rows.append({**row, "difference": difference, "difference / combined std": np.nan, "note": note})
    return pd.DataFrame(rows)
