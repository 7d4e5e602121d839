"""The measured domain of a calibration: where its data reached in joint space and in tool
orientation, and so where its claims hold (docs/methods.md, "Where a calibration holds").

- **Joint intervals**: per joint, [min, max] of the readings the fit used (the optimization set's
  rows whose marker was seen and that were not flagged as gross errors), rad. A joint whose readings
  span less than `HELD_WIDTH` is *held*: an interval of zero width, at its value. The share of its
  range they cover is of the limits' interval, or of the circle where the limits span a turn or
  more (a UR's +-2 pi: readings one turn apart are one configuration).
- **Tool orientations**: the largest angle between a measured flange z axis and their mean direction
  (nominal kinematics), deg.
- **Nearness** (`robot.nearness.Nearness`): how far the marker moves from the nearest measured
  configuration, each joint's difference weighted by its lever arm to the marker; a configuration
  is *near the data* when that distance is at most the data's own spacing. The joint intervals are
  a box around a thin set (a design that keeps the tool facing the sensor leaves most of its box
  unmeasured), so the claims are made near the data, not in the box.
- **Domain configurations** (`MeasuredDomain.configurations`): random configurations near the data
  (a measured configuration moved by at most the data's spacing, within the limits), from the
  generator of (seed, 'domain', robot slug): the same for the same robot, seed and data.

Where the claims hold (`MeasuredDomain.holds`): "across the joint limits" when every joint's interval
covers at least `FULL_RANGE_FRACTION` of its range (limits, +-pi where unlimited) and the measured tool
axes spread at least `MIN_TOOL_SPREAD_DEG` (joints that each moved far, but in combinations that
kept the tool pointing one way, leave the other orientations unmeasured: kuka-cubes); otherwise
"near the measured configurations", naming what falls short. The claim across the limits is still made, apart: there
the parameters the data did not determine spread by their priors.

SI inside (rad); degrees only in the texts and in `report()`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .. import identity, seeding
from ..inference import metrics
from ..robot.kinematics import ForwardKinematics, KinematicChain
from ..robot.nearness import HELD_WIDTH, Nearness, circle_arcs
from ..units import DEG

FULL_RANGE_FRACTION = 0.9  # share of each joint's range the data must span for claims across the limits
MIN_TOOL_SPREAD_DEG = 30.0  # and the spread of the measured tool axes
ACROSS, INSIDE = "across the joint limits", "near the measured configurations"
TURN = 2.0 * np.pi * (1.0 - 1e-12)  # rad: limits spanning this (a turn, up to round-off) cover the whole circle


@dataclass(frozen=True, eq=False)
class MeasuredDomain:
    """lower, upper (N,) rad: each joint's measured interval; limits_lower, limits_upper (N,) rad:
    its limits (+-pi where unlimited); tool_axis_spread_deg: the largest angle between a measured
    flange z axis and their mean direction; nearness: how near a configuration is to the measured
    ones (`robot.nearness`)."""

    lower: np.ndarray
    upper: np.ndarray
    limits_lower: np.ndarray
    limits_upper: np.ndarray
    tool_axis_spread_deg: float
    nearness: Nearness

    @classmethod
    def of(cls, chain: KinematicChain, q, marker) -> MeasuredDomain:
        """The domain of readings q (n, N) rad, n >= 1, of a marker (3,) m in the flange frame."""
        q = np.atleast_2d(np.asarray(q, dtype=float))
        lower, upper = metrics.joint_space_bounds(chain)
        axes = ForwardKinematics(chain, q).flange_poses()[:, :3, 2]
        mean = axes.mean(axis=0)
        mean /= np.linalg.norm(mean)
        spread = float(np.degrees(np.arccos(np.clip(axes @ mean, -1.0, 1.0))).max())
        low, high = q.min(axis=0), q.max(axis=0)
        held = high - low < HELD_WIDTH
        centre = 0.5 * (low + high)  # a held joint: one value
        nearness = Nearness.of(chain, q, marker)
        return cls(np.where(held, centre, low), np.where(held, centre, high), lower, upper, spread, nearness)

    @property
    def held(self) -> np.ndarray:
        """Boolean (N,): the joints whose readings never moved (interval of zero width)."""
        return self.upper - self.lower == 0.0

    @property
    def range_fraction(self) -> np.ndarray:
        """(N,) the share of each joint's range its readings cover: of its limits' interval, or, for
        a joint whose limits span a turn or more, of the circle (`nearness.circle_arcs`: readings
        a turn apart are one configuration of the geometry, so limits of two turns are covered by
        readings over one); 0 for a held joint."""
        span = self.limits_upper - self.limits_lower
        _, arcs = circle_arcs(self.nearness.measured)
        fraction = np.where(span >= TURN, arcs / (2.0 * np.pi), (self.upper - self.lower) / span)
        return np.where(self.held, 0.0, fraction)

    @property
    def covers_the_limits(self) -> bool:
        return bool(
            self.range_fraction.min() >= FULL_RANGE_FRACTION and self.tool_axis_spread_deg >= MIN_TOOL_SPREAD_DEG
        )

    def configurations(self, robot: str, n: int, seed: int) -> np.ndarray:
        """n configurations (n, N) rad near the data (`Nearness.draw`, within the limits; a held
        joint stays at its value), from the generator of (seed, 'domain', robot slug)."""
        rng = seeding.generator(seed, "domain", identity.robot_slug(robot))
        q = self.nearness.draw(n, rng, self.limits_lower, self.limits_upper)
        return np.where(self.held, self.lower, q)

    def ranges_text(self) -> str:
        """Each joint's interval in degrees: 'q1 -161 to 167 deg (96 % of its range), ..., q3 held at 0 deg'."""
        parts = []
        for j, (low, high, fraction) in enumerate(zip(self.lower, self.upper, self.range_fraction)):
            if low == high:
                parts.append(f"q{j + 1} held at {low / DEG:.0f} deg")
            else:
                parts.append(f"q{j + 1} {low / DEG:.0f} to {high / DEG:.0f} deg ({100 * fraction:.0f} % of its range)")
        return ", ".join(parts)

    def short_text(self) -> str:
        """What falls short of the claims across the limits: 'q3 held at 0 deg; tool axes within 18 deg
        of one direction' (joints under FULL_RANGE_FRACTION with their share, then the tool axes)."""
        parts = [
            f"q{j + 1} held at {low / DEG:.0f} deg"
            if low == high
            else f"q{j + 1} over {100 * fraction:.0f} % of its range"
            for j, (low, high, fraction) in enumerate(zip(self.lower, self.upper, self.range_fraction))
            if fraction < FULL_RANGE_FRACTION
        ]
        if self.tool_axis_spread_deg < MIN_TOOL_SPREAD_DEG:
            parts.append(f"tool axes within {self.tool_axis_spread_deg:.0f} deg of one direction")
        return "; ".join(parts)

    def holds(self) -> str:
        """Where the claims hold: ACROSS, or INSIDE with what falls short of the limits (the ranges
        themselves are the certificate's "Valid for", `ranges_text`): 'near the measured configurations
        (q3 held at 0 deg; tool axes within 18 deg of one direction)'."""
        if self.covers_the_limits:
            return ACROSS
        return f"{INSIDE} ({self.short_text()})"

    def report(self) -> dict:
        """JSON-ready: per joint the interval (deg), its share of the range and whether it was held;
        the tool axes' spread, the thresholds, and where the claims hold."""
        return {
            "joints": [
                {
                    "joint": f"q{j + 1}",
                    "lower_deg": float(low / DEG),
                    "upper_deg": float(high / DEG),
                    "range_fraction": float(fraction),
                    "held": bool(low == high),
                }
                for j, (low, high, fraction) in enumerate(zip(self.lower, self.upper, self.range_fraction))
            ],
            "held_joints": [f"q{j + 1}" for j in np.flatnonzero(self.held)],
            "near": {
                "measured_configurations": int(len(self.nearness.measured)),
                "spacing_mm": float(self.nearness.radius * 1e3),
                "lever_arms_mm": [float(r * 1e3) for r in self.nearness.lever],
                "meaning": "a configuration is near the data when the marker moves at most spacing_mm (to first "
                "order) from the nearest measured configuration",
            },
            "tool_axis_spread_deg": self.tool_axis_spread_deg,
            "full_range_fraction": FULL_RANGE_FRACTION,
            "min_tool_spread_deg": MIN_TOOL_SPREAD_DEG,
            "covers_the_limits": self.covers_the_limits,
            "ranges": self.ranges_text(),
            "short_of_the_limits": self.short_text(),
            "holds": self.holds(),
        }
