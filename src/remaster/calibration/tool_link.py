"""Where a tool sits on the flange, from a calibration measured at one marker.

One marker per row moves alike whether the marker sits off its nominal point (its mount, u) or the
flange does (the tool link's small motion, `link_geometry`'s F_tool: translation t and rotation r,
F'_tool = F_tool D(t, r)): the data fix the marker's total offset in the flange frame,

    o = u + t + r x m                      (m the marker's nominal point),

and nothing of how it splits. A tool point p moves with the flange alone:

    s = t + r x p.

With the priors' independent Gaussians (u, t, r per axis with stds sigma_u, sigma_t, sigma_r: the
`marker_offset_mm`, `link_translation_mm` and `link_rotation_deg` priors), s given o is Gaussian
(linear-Gaussian conditioning): mean K o, covariance C_ss - K C_os, K = C_so C_oo^-1, where
C_oo = (sigma_u^2 + sigma_t^2) I + sigma_r^2 [m]x [m]x^T, C_so = sigma_t^2 I + sigma_r^2 [p]x [m]x^T and
C_ss = sigma_t^2 I + sigma_r^2 [p]x [p]x^T. The covariance is what the priors, not the data, set: a
TCP's place relative to the marker is not determined by one marker per row, and its bound says so.

SI (m, rad).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .. import spatial


@dataclass(frozen=True)
class ToolSplit:
    """The tool point's shift s (flange frame, m) given the marker's offset o: s = gain o + e,
    e ~ N(0, covariance). gain (3, 3); covariance (3, 3) m^2."""

    gain: np.ndarray
    covariance: np.ndarray

    @classmethod
    def of(cls, marker, point, marker_std: float, translation_std: float, rotation_std: float) -> ToolSplit:
        """The split for a tool `point` (3,) m of a calibration measured at `marker` (3,) m (both
        flange frame), priors per axis: the marker's mount (m), the tool link's translation (m)
        and rotation (rad)."""
        at_marker = spatial.skew(np.asarray(marker, dtype=float))
        at_point = spatial.skew(np.asarray(point, dtype=float))
        eye = np.eye(3)
        c_oo = (marker_std**2 + translation_std**2) * eye + rotation_std**2 * at_marker @ at_marker.T
        c_so = translation_std**2 * eye + rotation_std**2 * at_point @ at_marker.T
        c_ss = translation_std**2 * eye + rotation_std**2 * at_point @ at_point.T
        gain = np.linalg.solve(c_oo, c_so.T).T
        covariance = c_ss - gain @ c_so.T
        return cls(gain, 0.5 * (covariance + covariance.T))

    @property
    def std(self) -> np.ndarray:
        """(3,) m: the shift's std per flange axis the priors leave."""
        return np.sqrt(np.clip(np.diag(self.covariance), 0.0, None))

    def mean(self, offset) -> np.ndarray:
        """(..., 3) m: the expected shift given marker offsets (..., 3) m."""
        return np.asarray(offset, dtype=float) @ self.gain.T

    def draw(self, offsets, rng: np.random.Generator) -> np.ndarray:
        """(K, 3) m: one shift per marker offset (K, 3) m (a posterior draw each), drawn from rng."""
        offsets = np.atleast_2d(np.asarray(offsets, dtype=float))
        values, vectors = np.linalg.eigh(self.covariance)
        root = vectors * np.sqrt(np.clip(values, 0.0, None))
        return self.mean(offsets) + rng.standard_normal(offsets.shape) @ root.T
