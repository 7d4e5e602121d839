"""From one sensor's campaign data to a posterior ready for sampling (paper, section Optimization).

1. Initial registration T_NR: the paper's three-point method on three measured configurations
   of the optimization set chosen far apart (nominal forward kinematics gives their robot-frame
   positions); a least-squares (Kabsch) registration over every point is reported beside it.
2. Identifiability: the Jacobian of the full model at zero corrections; each undetermined
   combination gets one parameter held at the controller's value (`remaster.identifiability`).
3. The posterior over the free parameters and sigma, as a `PosteriorTarget` that every sampler
   takes.
Points whose marker was not seen are excluded from the fit and listed.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from . import identifiability, registration
from .campaign import SensorData
from .kinematics import ForwardKinematics, KinematicChain
from .model import SIGMA, ZeroOffsetModel, display_scale
from .spatial import transform_points


@dataclass(frozen=True)
class Registration:
    """Initial sensor <- robot transform and how it was obtained. Rows are 0-based rows of the
    sensor table; RMS values are per-axis residuals (m) over the set's measured points."""

    t_nr: np.ndarray
    rows: tuple[int, int, int]
    kabsch_t_nr: np.ndarray
    three_point_rms: float
    kabsch_rms: float

    def report(self) -> dict:
        rotation_difference = self.t_nr[:3, :3].T @ self.kabsch_t_nr[:3, :3]
        angle = np.degrees(np.arccos(np.clip((np.trace(rotation_difference) - 1) / 2, -1, 1)))
        return {"method": "three-point (paper)", "rows": list(self.rows), "T_NR": self.t_nr.tolist(),
                "kabsch_T_NR": self.kabsch_t_nr.tolist(),
                "three_point_rms_mm": self.three_point_rms * 1e3, "kabsch_rms_mm": self.kabsch_rms * 1e3,
                "three_point_vs_kabsch": {
                    "translation_mm": float(np.linalg.norm(self.t_nr[:3, 3] - self.kabsch_t_nr[:3, 3]) * 1e3),
                    "rotation_deg": float(angle)}}


def measured_rows(sensor: SensorData, set_name: str) -> np.ndarray:
    """0-based table rows of a set whose marker was seen."""
    return np.flatnonzero(sensor.set_mask(set_name) & sensor.measured_mask)


def register(chain: KinematicChain, sensor: SensorData, set_name: str = "optimization") -> Registration:
    """The paper's three-point registration from three far-apart measured configurations of the
    set, with a Kabsch registration over all of them for comparison."""
    rows = measured_rows(sensor, set_name)
    q = sensor.table[list(sensor.joint_columns)].to_numpy(float)[rows]
    measured = sensor.table[["x", "y", "z"]].to_numpy(float)[rows]
    robot = ForwardKinematics(chain, q).points(sensor.marker)
    triple = registration.spread_out_triple(measured)
    three = registration.three_point(robot[triple], measured[triple])
    kabsch = registration.kabsch(robot, measured)

    def rms(t_nr):
        return float(np.sqrt(np.mean((transform_points(t_nr, robot) - measured) ** 2)))

    return Registration(three, tuple(int(r) for r in rows[triple]), kabsch, rms(three), rms(kabsch))


def build_model(chain: KinematicChain, sensor: SensorData, t_nr, set_name: str = "optimization"):
    """(model with undetermined parameters held, identifiability analysis, excluded rows)."""
    rows = measured_rows(sensor, set_name)
    q = sensor.table[list(sensor.joint_columns)].to_numpy(float)[rows]
    measured = sensor.table[["x", "y", "z"]].to_numpy(float)[rows]
    analysis = identifiability.analyse(ZeroOffsetModel(chain, q, measured, sensor.marker, t_nr))
    model = ZeroOffsetModel(chain, q, measured, sensor.marker, t_nr, fixed=analysis.held)
    excluded = np.flatnonzero(sensor.set_mask(set_name) & ~sensor.measured_mask)
    return model, analysis, excluded


@dataclass(frozen=True)
class PosteriorTarget:
    """The log-posterior of a model over (free parameters..., noise.sigma), for the samplers."""

    model: ZeroOffsetModel

    @property
    def names(self) -> tuple[str, ...]:
        return self.model.names + (SIGMA,)

    @property
    def scale(self) -> np.ndarray:
        return np.array([display_scale(n) for n in self.names])

    def log_prob(self, theta) -> float:
        theta = np.asarray(theta, dtype=float)
        return float(self.model.log_posterior(theta[:-1], theta[-1]))

    def log_prob_many(self, thetas) -> np.ndarray:
        thetas = np.asarray(thetas, dtype=float)
        return self.model.log_posterior(thetas[:, :-1], thetas[:, -1])

    def residuals(self, theta_model) -> np.ndarray:
        """Residual vector (3n,) of the model parameters (sigma excluded), for least squares."""
        return self.model.residuals(theta_model).ravel()
