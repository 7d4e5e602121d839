"""What the selection cross-validates over: folds of whole poses (`selection_folds`), blocks of
poses contiguous in time (`TimeBlocked`) and held-out regions of the domain (`Regions`), and the
fall over K folds an effect needs (`cv_threshold`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ..inference import evidence
from ..inference.gp import loop_candidate
from ..inference.readings import Readings
from ..robot.kinematics import KinematicChain, flange_rotations
from ..units import MM
from .candidates import GP
from .fitted import Fitted
from .settings import LoopSettings


def selection_folds(poses, n_folds: int) -> np.ndarray:
    """(n,) the cross-validation folds of the selection: `n_folds` folds of whole poses, or one pose
    per fold when the campaign has fewer poses (each score carries its `cv_folds`, and the t(K - 1)
    threshold is held at that K: a campaign of few poses needs a larger fall). A single pose cannot
    be registered (`remaster.robot.registration`), so it never reaches the loop."""
    return evidence.pose_folds(poses, max(2, min(n_folds, len(np.unique(np.asarray(poses))))))


def fold_warning(poses, settings: LoopSettings) -> str | None:
    """The warning a campaign of fewer poses than `cv_folds` gets (`selection_folds`), or None."""
    n_poses, n_folds = len(np.unique(np.asarray(poses))), settings.cv_folds
    if n_poses >= n_folds:
        return None
    return (
        f"only {n_poses} poses in the optimization set: the loop closure cross-validates over {n_poses} folds "
        f"of one pose (not {n_folds}); an effect needs a fall of {cv_threshold(settings, n_poses):.3g} "
        "standard errors at the same level"
    )


def cv_threshold(settings: LoopSettings, n_folds: int | None = None) -> float:
    """The cross-validated fall (in standard errors over the folds) an effect needs: the one-sided
    level of `cv_standard_errors` normal standard errors, held at Student's t with K - 1 degrees of
    freedom (`evidence.t_threshold`; K = 5 folds at 2.0: 2.87)."""
    return evidence.t_threshold(settings.cv_standard_errors, n_folds or settings.cv_folds)


@dataclass(frozen=True, eq=False)
class TimeBlocked:
    """Cross-validation by blocks contiguous in time (`evidence.time_folds`) beside the pose-grouped
    folds the selection uses: how well each model predicts poses measured later (or earlier) than
    those it was fitted on, rather than among them. folds (n,); order: what the blocks follow."""

    folds: np.ndarray
    order: str

    @classmethod
    def of(cls, data: Readings, poses, n_folds: int) -> TimeBlocked | None:
        """Blocks in the order of the table's time column, or of its rows where it has none (the
        rows are then taken as the measurement order); None with fewer poses than blocks."""
        if data.drift is not None and data.drift_unit == "s":
            times, order = data.drift, "time column"
        else:
            times, order = data.rows.astype(float), "row order (no time column: taken as the measurement order)"
        try:
            return cls(evidence.time_folds(times, poses, n_folds), order)
        except ValueError:
            return None

    def report(
        self,
        path: Sequence[tuple[str, Fitted]],
        current: Fitted | None = None,
        data: Readings | None = None,
        rotation: np.ndarray | None = None,
        settings: LoopSettings | None = None,
    ) -> dict:
        """JSON-ready: the time-blocked cross-validated RMS per axis (mm) after each step of path
        ((name, fit) in order) and, given the GP's inputs, the residual GP on current's residuals
        scored over the time blocks (hyperparameters refitted without the held-out block, as with
        the pose folds): its fall, in standard errors, and its gain."""
        steps = {name: f.cross_validated(self.folds).rmse / MM / math.sqrt(3.0) for name, f in path}
        out = {
            "folds": int(len(np.unique(self.folds))),
            "order": self.order,
            "measure": "cross-validated RMS per axis, blocks of whole poses contiguous in time held out in turn",
            "rms_per_axis_mm": steps,
        }
        if current is not None:
            gain = self.gp_gain(current, data, rotation, settings)
            steps[GP] = gain["cv_rmse_mm"] / math.sqrt(3.0)
            out["residual_gp"] = {**gain, "structure_found": bool(gain["cv_mse_fall_in_se"] > cv_threshold(settings))}
        return out

    def gp_gain(self, current: Fitted, data: Readings, rotation: np.ndarray, settings: LoopSettings) -> dict:
        """The residual GP on current's residuals scored over the time blocks (hyperparameters
        refitted without the held-out block): `evidence.cv_gain` against current."""
        before = current.cross_validated(self.folds)
        gp = loop_candidate.fit_and_score(
            data.q,
            current.residuals() @ rotation,
            before.held_out @ rotation,
            self.folds,
            int(settings.residual_gp["subset"]),
            int(settings.residual_gp["inducing"]),
        )
        return evidence.cv_gain(before, evidence.CrossValidation(gp.mse, gp.points))


# Below this spread of the tool axis about its mean direction (deg) the campaign holds one tool
# orientation (a cube design's tool along one axis): regions of it would be cut from the noise of the
# inverse kinematics, not from orientations an effect could extrapolate to
TOOL_AXIS_SPREAD_DEG = 10.0
REGION_SEED = 0  # the k-means starts' seed: the same campaign is cut into the same regions


def region_features(chain: KinematicChain, q) -> dict[str, np.ndarray]:
    """The features regions are cut in, per fold set, at readings q (n, N) rad: 'joint_space' (n, 2N)
    cos and sin of each joint (a revolute joint is periodic: q and q + 2 pi are one configuration, and
    each joint's circle weighs alike), 'tool_axis' (n, 3) the flange's z axis in the robot frame (the
    tool's direction, which the joint space reaches by many configurations)."""
    q = np.asarray(q, dtype=float)
    return {
        "joint_space": np.column_stack([np.cos(q), np.sin(q)]),
        "tool_axis": flange_rotations(chain, q)[:, :, 2],
    }


@dataclass(frozen=True, eq=False)
class Regions:
    """Cross-validation by regions beside the pose folds and the time blocks: each fold a region of
    whole poses (`evidence.region_folds`, k-means of their features, `region_features`), held out in
    turn, so that a fold's fit predicts a part of the domain it did not see: what a calibration is
    bought for beyond its poses. folds: {set name: (n,) folds}; centres: {set name: (K, d)}; skipped:
    {set name: why it has no folds}."""

    folds: dict[str, np.ndarray]
    centres: dict[str, np.ndarray]
    skipped: dict[str, str]

    @classmethod
    def of(cls, chain: KinematicChain, data: Readings, poses, n_folds: int) -> Regions | None:
        """The regions of the readings' joint space and tool axis, K = n_folds of each; None with
        fewer poses than regions (then neither set can be cut)."""
        folds, centres, skipped = {}, {}, {}
        for name, features in region_features(chain, data.q).items():
            if name == "tool_axis":
                mean = features.mean(axis=0)
                mean /= max(np.linalg.norm(mean), np.finfo(float).tiny)
                spread = math.degrees(float(np.max(np.arccos(np.clip(features @ mean, -1.0, 1.0)))))
                if spread < TOOL_AXIS_SPREAD_DEG:
                    skipped[name] = f"one tool orientation (within {spread:.2g} deg of its mean)"
                    continue
            try:
                folds[name], centres[name] = evidence.region_folds(features, poses, n_folds, REGION_SEED)
            except ValueError as exc:
                skipped[name] = str(exc)
        return cls(folds, centres, skipped) if folds else None

    def report(self) -> dict:
        """JSON-ready: per fold set its regions and the rows held out in each, or why it has none."""
        return {
            "measure": "held-out regions of whole poses (k-means of the configurations' cos/sin of each joint, "
            "and of the flange's z axis); a candidate passes where the median log fall over every region is "
            "positive (`region_median_log_fall`)",
            "sets": {
                name: {"folds": len(c), "rows_per_fold": np.bincount(self.folds[name]).tolist()}
                for name, c in self.centres.items()
            },
            "skipped": dict(self.skipped),
        }
