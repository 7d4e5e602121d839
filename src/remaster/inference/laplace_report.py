"""The paper model's least-squares fit and its Laplace approximation (`laplace_fit`), reported
(`laplace_report`, laplace.json, with the identifiability analysis, the outliers and what a probe's
orientations add) and read back by the later stages (`LaplaceReport`).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from ..errors import report_reader
from ..files import read_json
from ..robot import gravity
from . import identifiability
from .blocks import BlockModel
from .least_squares import LaplaceResult, least_squares_laplace
from .posterior_targets import PosteriorTarget


def laplace_fit(model: BlockModel) -> LaplaceResult:
    """Least-squares MAP of the model parameters from zero corrections, with its Laplace covariance."""
    target = PosteriorTarget(model)
    return least_squares_laplace(target.residuals, np.zeros(len(model.names)), model.scale, names=model.names)


def laplace_report(
    result: LaplaceResult,
    analysis: identifiability.Identifiability,
    excluded_rows,
    outlier_rows=(),
    model: BlockModel | None = None,
) -> dict:
    """JSON-ready: the MAP, covariance and sigma (SI), the identifiability analysis, the rows
    left out (marker not seen; flagged as outliers), the number of points fitted, and the tool
    the chain's URDF carries (`gravity.tool_report`: the loop closure's gravity torques take it
    instead of the configured payload; None when it carries none or no model is given)."""
    return {
        "names": list(result.names),
        "theta_map": result.theta_map.tolist(),
        "covariance": result.covariance.tolist(),
        "std": result.std.tolist(),
        "sigma_map": result.sigma_map,
        "sigma_mean": result.sigma_mean,
        "sigma_std": result.sigma_std,
        "sum_squares": 2.0 * result.cost,
        "n_residuals": result.n_residuals,
        "jacobian_singular_values_step_units": result.jacobian_singular_values.tolist(),
        "identifiability": analysis.report(),
        "excluded_rows_marker_not_seen": [int(r) for r in excluded_rows],
        "excluded_rows_outliers": [int(r) for r in outlier_rows],
        "points_fitted": None if model is None else int(model.n_points),
        "urdf_tool": None if model is None else gravity.tool_report(model.chain),
    }


def orientation_added(
    result: LaplaceResult,
    analysis: identifiability.Identifiability,
    points: LaplaceResult,
    points_analysis: identifiability.Identifiability,
    model: BlockModel,
) -> dict:
    """What a full-pose probe's orientations added to the zero-offset fit, JSON-ready: the rows
    fitted with one, their weight (m/rad, `balanced_orientation`), the parameters held with points alone that the orientations determine, each
    fit's sigma and parameter stds (`points`, `points_analysis`: the same rows' points alone), and
    `information_ratio`: each std with the orientations over its std from the points alone at one
    sigma (std / sigma of each fit), the data's part; the stds' own ratio also carries the change of
    the one sigma."""
    points_std = dict(zip(points.names, points.std.tolist()))
    sigmas = result.sigma_map / points.sigma_map
    return {
        "orientations_fitted": int(model.n_orientations),
        "weight_m_per_rad": float(model.data.orientation_weight),
        "held_with_orientation": sorted(analysis.held),
        "held_with_points_alone": sorted(points_analysis.held),
        "determined_only_with_orientation": sorted(set(points_analysis.held) - set(analysis.held)),
        "sigma_with_orientation_m": float(result.sigma_map),
        "sigma_with_points_alone_m": float(points.sigma_map),
        "std_with_orientation": dict(zip(result.names, result.std.tolist())),
        "std_with_points_alone": points_std,
        "information_ratio": {
            n: float(s / points_std[n] / sigmas) for n, s in zip(result.names, result.std) if n in points_std
        },
    }


@dataclass(frozen=True, eq=False)
class LaplaceReport:
    """The paper model's Laplace fit of one sensor as the later stages read it (`laplace.json`,
    written by `laplace_report`; read by `LaplaceReport.read`). names (P,) free parameters;
    theta_map, std (P,) and covariance (P, P) SI; sigma_map, sigma_mean, sigma_std (m);
    parameters: every parameter in order, held ones included; held: {name: value} held at the
    controller's value; null_directions: the data's blind combinations ({name: weight} each);
    outlier_rows and marker_not_seen_rows: table rows left out of the fit;
    points_fitted (None when the report was made without the model); held_statements: one sentence
    per held parameter, saying what the data cannot tell apart; orientation: what a full-pose
    probe's orientations added (`orientation_added`), None for points alone; held_reasons: {held
    name: 'not identifiable' or 'not determined: std ...'} (`Identifiability.reasons`)."""

    names: tuple[str, ...]
    theta_map: np.ndarray
    std: np.ndarray
    covariance: np.ndarray
    sigma_map: float
    sigma_mean: float
    sigma_std: float
    parameters: tuple[str, ...]
    held: dict[str, float]
    null_directions: tuple[dict[str, float], ...]
    outlier_rows: tuple[int, ...]
    marker_not_seen_rows: tuple[int, ...]
    points_fitted: int | None
    held_statements: tuple[str, ...] = ()
    orientation: dict | None = None
    held_reasons: Mapping[str, str] | None = None

    @property
    def held_zero_offsets(self) -> dict[str, float]:
        """{zero-offset: value} held at the controller's value: the joints these data do not see."""
        return {n: v for n, v in self.held.items() if n.startswith("zero_offsets.")}

    @property
    def absorbed_by_registration(self) -> frozenset[str]:
        """The held zero-offsets a blind combination shares with the registration: a registration
        absorbs them (joint 1's turn about a vertical base axis, say), so no sensor frame sees them."""
        held = self.held_zero_offsets
        return frozenset(
            n
            for direction in self.null_directions
            if any(k.startswith("registration.") for k in direction)
            for n in direction
            if n in held
        )

    @classmethod
    def of(cls, content: Mapping, source: str = "laplace.json") -> LaplaceReport:
        """From the JSON content; a missing key is an InputError naming the file and the key."""
        get = report_reader(content, source, "missing in the Laplace report")
        return cls(
            names=tuple(get("names")),
            theta_map=np.asarray(get("theta_map"), dtype=float),
            std=np.asarray(get("std"), dtype=float),
            covariance=np.asarray(get("covariance"), dtype=float),
            sigma_map=float(get("sigma_map")),
            sigma_mean=float(get("sigma_mean")),
            sigma_std=float(get("sigma_std")),
            parameters=tuple(get("identifiability", "parameters")),
            held={n: float(v) for n, v in get("identifiability", "held_at_controller_value").items()},
            null_directions=tuple(dict(d) for d in get("identifiability", "null_directions")),
            outlier_rows=tuple(int(r) for r in get("excluded_rows_outliers")),
            marker_not_seen_rows=tuple(int(r) for r in get("excluded_rows_marker_not_seen")),
            points_fitted=None if get("points_fitted") is None else int(get("points_fitted")),
            held_statements=tuple(str(x) for x in get("identifiability", "statements")),
            orientation=content.get("orientation"),
            held_reasons=dict(get("identifiability").get("held_reasons") or {}),
        )

    @classmethod
    def read(cls, path) -> LaplaceReport:
        """From laplace.json; InputError naming the file, and the key when one is missing."""
        return cls.of(read_json(path), source=str(path))

    @property
    def orientation_weight(self) -> float | None:
        """The weight (m/rad) the fit gave a full-pose probe's orientations (`balanced_orientation`),
        None for points alone: every later stage that rebuilds the model takes it."""
        return None if not self.orientation else float(self.orientation["weight_m_per_rad"])

    @property
    def held_with_points_alone(self) -> dict[str, float]:
        """{name: value} held by a model of the points alone (the loop closure's): `held`, plus what a
        full-pose probe's orientations determined and the points alone do not, held at this fit's
        value (the points cannot move it; the calibration's outputs then carry it)."""
        if not self.orientation:
            return dict(self.held)
        estimate = dict(zip(self.names, self.theta_map.tolist()))
        return {**{n: estimate.get(n, 0.0) for n in self.orientation["held_with_points_alone"]}, **self.held}

    def check_names(self, names) -> None:
        """The fitted model's free parameters must be the report's: else the report belongs to
        another model (another campaign, or the fit has changed since)."""
        if tuple(names) != self.names:
            raise ValueError(f"the Laplace fit's parameters {list(self.names)} are not the model's {list(names)}")

    def start(self) -> tuple[np.ndarray, np.ndarray]:
        """(start (P + 1,), covariance (P + 1, P + 1)) of the samplers: the MAP and its Laplace
        covariance, sigma last (its std on the diagonal)."""
        theta = np.append(self.theta_map, self.sigma_map)
        covariance = np.zeros((len(theta), len(theta)))
        covariance[:-1, :-1] = self.covariance
        covariance[-1, -1] = self.sigma_std**2
        return theta, covariance
