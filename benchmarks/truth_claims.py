"""The benchmarks' door onto `remaster.api.truth` (a calibration of a simulated campaign held to
the truth it was simulated from), with the config.yaml the workflow runs; and the least-squares
baseline some benchmarks set beside the loop closure.

`check` is `remaster.api.truth.check` with this repository's config.yaml and root (the campaign's
shared URDF), taking its probe's fields as arguments (benchmarks/bench_truth_claims.py,
bench_cyclic_case.py, bench_coverage.py, bench_transfer.py).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from remaster import files
from remaster.api import truth
from remaster.api.truth import Claim, TruthCheck, own_posterior_expectations, posterior_outside
from remaster.calibration import prediction
from remaster.inference import evidence
from remaster.inference.extensions import extended_model
from remaster.inference.parameter_blocks import EXTENSIONS
from remaster.inference.readings import readings
from remaster.loop.fitted import accuracy

REPO = Path(__file__).resolve().parents[1]
__all__ = ["REPO", "Claim", "TruthCheck", "check", "least_squares_validation", "own_posterior_expectations"]
__all__ += ["posterior_outside"]


def check(
    spec: dict,
    chain,
    sensor: str,
    n_random: int = 300,
    draws: int = 1000,
    seed: int = 5,
    without: tuple = (),
    elsewhere_q=None,
) -> TruthCheck:
    """`truth.check` of `spec` with config.yaml's settings (`truth.Probe`'s fields as arguments)."""
    probe = truth.Probe(n_random, draws, seed, tuple(without), files.read_yaml(REPO / "config.yaml"))
    return truth.check(spec, chain, sensor, probe, elsewhere_q, REPO)


def least_squares_validation(campaign, sensor: str, registered, laplace, settings, extensions, priors=None) -> dict:
    """The baseline a calibration engineer would fit: least squares of the paper's model plus
    `extensions` (e.g. every link's six parameters, the marker offset, joint compliance) on the
    optimization rows the paper's fit kept; flat (`priors` None: what the data cannot see held at 0,
    by the loop's own reduction) or under `priors`; the gravity torques as `settings.model` gives
    them on this campaign's chain. Returns the validation set's accuracy (`fitted.accuracy`:
    rmse_mm, rms_per_axis_mm, ...; the validation set is read for this only), the parameters fitted
    and, as `calibration`, the fit as a `prediction.Calibration` (model 'least_squares': the robot's
    parameters, the registration left out, as a loop-closed model's) that `comparing.transfer`
    applies to another campaign."""
    data = campaign.sensors[sensor]
    fitted_on = readings(campaign.chain, data, "optimization", settings.model, exclude=laplace.outlier_rows)
    checked_on = readings(campaign.chain, data, "validation", settings.model)
    model, _ = extended_model(
        campaign.chain, fitted_on, data.marker, registered.t_nr, extensions, dict(laplace.held), priors
    )
    theta = evidence.posterior_mode(model, np.zeros(len(model.names))).theta
    validation = model.on(checked_on)
    poses = data.table["pose"].to_numpy()[checked_on.rows]
    values = {
        name: float(value)
        for name, value in zip(model.all_names, model.full(theta))
        if model.block_of[name] not in prediction.SETUP_BLOCKS
    }
    kept = tuple(b for b in model.blocks if b in EXTENSIONS and b not in prediction.SETUP_BLOCKS)
    return {
        **accuracy(validation.measured, validation.predict(theta), poses),
        "parameters": len(theta),
        "calibration": prediction.Calibration("least_squares", values, kept, settings.model),
    }
