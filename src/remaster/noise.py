"""A laser tracker's noise as it is: range and transverse, the transverse growing with distance.

A tracker measures a distance (interferometer or ADM) and two angles. Its range noise does not
depend on the distance; its transverse noise is the angle noise times the distance, on top of a
floor of the size of the range noise. In the tracker's own frame (origin at the tracker head),
with u_i the unit direction and d_i the distance of row i's measured point,

    S_i = sigma^2 (u_i u_i^T + k_i^2 (I - u_i u_i^T)),    k_i^2 = 1 + (g d_i)^2,

sigma the range std (free, Jeffreys' prior as for the isotropic model) and g (1/m) the growth of
the transverse std relative to it. The fit works on whitened residuals W_i e_i with
W_i = S_i^-1/2 sigma = u_i u_i^T + (I - u_i u_i^T) / k_i, and the likelihood gains
-1/2 sum log|S_i / sigma^2| = -2 sum log k_i, which makes evidences of different g comparable
with each other and with the isotropic model (g = 0).

g's prior is log-normal around the specification of a typical tracker: datasheets give a
maximum permissible error of about 15 um + 6 um/m transversely and 10 um in range (e.g. Leica
AT960), i.e. a transverse std that grows by about its range std per metre: g ~ 1 /m, uncertain
by a factor of 3. Its value is the mode of log Z(g) + log prior(g); the model's evidence
integrates g by a Laplace step in log g. The isotropic model stays unless the anisotropic one
gains the loop's evidence threshold (the same rule as an effect's).

Only meaningful when the sensor frame is the tracker's own (its head at the origin): a campaign
whose positions were already moved into the robot frame has the wrong directions, and the
evidence then decides against it or says what it sees.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from . import spatial

BASE_CLEARANCE_M = 0.25  # a tracker head stands at least this far from the robot's base origin
GROWTH_PRIOR_PER_M = 1.0  # median of g (1/m): the datasheet ratio in the module docstring
GROWTH_PRIOR_LOG_STD = math.log(3.0)  # g uncertain by a factor of 3 either way


@dataclass(frozen=True)
class RangeTransverse:
    """S_i = sigma^2 (u u^T + (1 + (growth_per_m d_i)^2) (I - u u^T)) in the sensor frame, whose
    origin is the tracker head (module docstring)."""

    growth_per_m: float

    def ratios(self, measured) -> np.ndarray:
        """k_i (n,): transverse std over range std at each measured point (n, 3) m."""
        distance = np.linalg.norm(np.asarray(measured, dtype=float), axis=-1)
        return np.sqrt(1.0 + (self.growth_per_m * distance) ** 2)

    def whitening(self, measured) -> np.ndarray:
        """W_i (n, 3, 3): sigma S_i^-1/2 at measured points (n, 3) m."""
        measured = np.asarray(measured, dtype=float)
        u = measured / np.linalg.norm(measured, axis=-1, keepdims=True)
        along = u[:, :, None] * u[:, None, :]
        return along + (np.eye(3) - along) / self.ratios(measured)[:, None, None]

    def log_det_term(self, measured) -> float:
        """-1/2 sum log|S_i / sigma^2| = -2 sum log k_i: what the likelihood gains beside the
        whitened sum of squares and -3n log sigma."""
        return float(-2.0 * np.sum(np.log(self.ratios(measured))))

    def report(self) -> dict:
        return {
            "model": "range_transverse",
            "transverse_growth_per_m": self.growth_per_m,
            "covariance": "sigma^2 (u u^T + (1 + (g d)^2) (I - u u^T)), u and d the direction and distance "
            "from the tracker head (the sensor frame's origin); sigma the range std",
        }


def frame_problem(t_nr, measured) -> str | None:
    """Why the sensor frame cannot be the tracker's own, or None: its origin (the head) would be
    at the robot's base (positions already moved into the robot frame) or among the measured
    points. t_nr (4, 4) robot -> sensor; measured (n, 3) m in the sensor frame."""
    head = spatial.invert(t_nr)[:3, 3]  # the sensor frame's origin in the robot frame
    if np.linalg.norm(head) < BASE_CLEARANCE_M:
        return (
            f"the sensor frame's origin is {np.linalg.norm(head):.3f} m from the robot's base origin: the "
            "positions are not in the tracker's own frame (already in the robot frame?), so the directions "
            "and distances from its head are unknown"
        )
    closest = float(np.min(np.linalg.norm(np.asarray(measured, dtype=float), axis=-1)))
    if closest < BASE_CLEARANCE_M:
        return f"a measured point is {closest:.3f} m from the sensor frame's origin: it cannot be the tracker's head"
    return None


def log_growth_prior(
    log_growth: float, median: float = GROWTH_PRIOR_PER_M, log_std: float = GROWTH_PRIOR_LOG_STD
) -> float:
    """Normalised log density of log g under the log-normal prior."""
    z = (log_growth - math.log(median)) / log_std
    return -0.5 * z * z - math.log(log_std) - 0.5 * math.log(2.0 * math.pi)
