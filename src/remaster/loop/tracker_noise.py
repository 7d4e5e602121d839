"""A laser tracker's range/transverse noise against the isotropic noise (`choose_noise`): its growth
at the mode of its evidence under its prior, taken when it gains enough, with the residual Gaussian
process present when it was added.
"""

from __future__ import annotations

import math

import numpy as np  # scipy is imported in the functions that use it (test_architecture: light readers)

from .. import noise
from ..inference import evidence
from ..inference.blocks import BlockModel
from ..inference.gp import with_parameters
from ..inference.gp.kernels import Hyperparameters
from ..units import MM
from . import noise_floor
from .fitted import Fitted
from .settings import LoopSettings

NOISE_SEARCH_WIDTH = 3.0  # prior stds of log g either side of its median searched for the mode


def choose_noise(
    current: Fitted,
    folds: np.ndarray,
    settings: LoopSettings,
    q=None,
    hyper: Hyperparameters | None = None,
    floor: float | None = None,
) -> tuple[Fitted, dict]:
    """The current model with a laser tracker's range/transverse noise (`remaster.noise`) against
    its isotropic noise: g at the mode of log Z(g) + log prior(g), the model's evidence with g
    integrated by a Laplace step in log g; taken when it gains `min_log_evidence_gain`. With the
    residual GP added (its hyperparameters `hyper`, readings q (n, N)), every evidence is taken with
    the GP present (`remaster.inference.gp.with_parameters`), so the noise shape is chosen after the residual
    model, for what the residual model leaves. A shape whose range std is above
    `noise_floor.NOISE_MODEL_RATIO` times the instrument's noise floor `floor` (m; None: not known)
    took up error the model lacks (a symptom, not the sensor's noise; the transverse std may grow
    beyond the floor, the range std may not): not kept, and the report says why (`refused`).
    Returns the chosen fit and a JSON-ready report."""
    import scipy.optimize

    prior = settings.tracker_noise
    median, log_std = float(prior["growth_per_m"]), math.log(float(prior["growth_factor"]))
    gp_present = hyper is not None
    dense = gp_present and len(q) <= with_parameters.MAX_NOISE_ROWS

    def mode_at(log_growth: float) -> evidence.PosteriorMode:
        return evidence.posterior_mode(
            current.model.with_noise(noise.RangeTransverse(math.exp(log_growth))), current.theta
        )

    if gp_present:  # the parameters and the GP integrated, the noise's scale at its maximum for each shape
        unit_shapes = {None: _noise_shapes(current.model, current.model)}

        def log_z_at(log_growth: float | None) -> float:
            if log_growth not in unit_shapes:
                growth = noise.RangeTransverse(math.exp(log_growth))
                unit_shapes[log_growth] = _noise_shapes(current.model, current.model.with_noise(growth))
            shapes = unit_shapes[log_growth]
            if dense:
                at_sigma = lambda sigma: with_parameters.noise_shape_log_evidence(  # noqa: E731
                    current.mode, q, hyper, sigma**2 * shapes
                )
            else:  # through inducing inputs: the sums over rows once per shape, each sigma then cheap
                at_sigma = with_parameters.ShapedNoiseEvidence(current.mode, q, hyper, shapes)
            found = scipy.optimize.minimize_scalar(
                lambda log_sigma: -at_sigma(math.exp(log_sigma)),
                bounds=(math.log(hyper.noise_std) - 3.0, math.log(hyper.noise_std) + 3.0),
                method="bounded",
                options={"xatol": 0.01},
            )
            return -found.fun

        isotropic = log_z_at(None)
    else:

        def log_z_at(log_growth: float) -> float:
            return mode_at(log_growth).log_evidence

        isotropic = current.mode.log_evidence

    def objective(log_growth: float) -> float:
        return -(log_z_at(log_growth) + noise.log_growth_prior(log_growth, median, log_std))

    centre, width = math.log(median), NOISE_SEARCH_WIDTH * log_std
    best = scipy.optimize.minimize_scalar(
        objective, bounds=(centre - width, centre + width), method="bounded", options={"xatol": 0.05}
    )
    step = 0.1  # in log g: the posterior of log g is wider than this wherever the data leave g free
    curvature = (objective(best.x + step) - 2.0 * best.fun + objective(best.x - step)) / step**2
    curvature = max(curvature, 1.0 / log_std**2)  # the prior alone curves this much; a noisy difference may not
    log_evidence = -best.fun + 0.5 * math.log(2.0 * math.pi) - 0.5 * math.log(curvature)
    gain = log_evidence - isotropic
    mode = mode_at(best.x)
    growth = math.exp(best.x)
    distance = np.linalg.norm(current.model.measured, axis=1)
    chosen = bool(gain > settings.min_log_evidence_gain)
    refused = None
    # along the beam no transverse growth widens the noise: a range std above the floor is model error
    if chosen and floor is not None and mode.sigma > noise_floor.NOISE_MODEL_RATIO * floor:
        chosen, refused = (
            False,
            f"it gains {gain:.1f} nats, but its range std ({mode.sigma / MM:.3g} mm) is {mode.sigma / floor:.1f} x "
            f"the instrument's noise floor ({floor / MM:.3g} mm): it takes up error the model lacks, not the "
            "sensor's noise; the isotropic noise is kept",
        )
    report = {
        "offered": True,
        "compared": "range/transverse (laser tracker) against isotropic",
        **noise.RangeTransverse(growth).report(),
        "prior": {"growth_per_m_median": median, "growth_factor": float(prior["growth_factor"])},
        "growth_std_log": 1.0 / math.sqrt(curvature),
        "residual_model": "residual_gp present (gp_joint; the noise's scale at its maximum for each shape)"
        if dense
        else "residual_gp present (gp_joint through "
        f"{with_parameters.NOISE_INDUCING} inducing inputs above {with_parameters.MAX_NOISE_ROWS} rows, Titsias' "
        "bound; the noise's scale at its maximum for each shape)"
        if gp_present
        else "the parametric effects (no residual GP added)",
        "log_evidence_isotropic": isotropic,
        "log_evidence_range_transverse": float(log_evidence),
        "log_evidence_gain": float(gain),
        "sigma_isotropic_mm": current.mode.sigma / MM,
        "sigma_range_mm": mode.sigma / MM,
        "sigma_transverse_at_median_distance_mm": mode.sigma
        * math.sqrt(1.0 + (growth * float(np.median(distance))) ** 2)
        / MM,
        "median_distance_m": float(np.median(distance)),
        "noise_floor_mm": None if floor is None else floor / MM,
        "chosen": "range_transverse" if chosen else "isotropic",
        **({"refused": refused} if refused else {}),
        "note": "sigma of the chosen range/transverse model is the range std; the transverse std grows with "
        "the distance from the sensor frame's origin, which must be the tracker head",
    }
    if not chosen:
        return current, report
    return Fitted(mode, current.reduction, evidence.cross_validate(mode, folds)), report


def _noise_shapes(model: BlockModel, shaped: BlockModel) -> np.ndarray:
    """(n, 3, 3): the covariance over sigma^2 of each row's noise under `shaped`'s noise model, in the
    coordinates of `model`'s whitened residuals (M (S / sigma^2) M^T, M model's whitening)."""
    whitening = model.whitening_matrices()  # (n, 3, 3): M_i, column a = M_i e_a
    shaped_whitening = shaped.whitening_matrices()
    inverse = np.linalg.inv(shaped_whitening)  # S_i / sigma^2 = W_i^-1 W_i^-T
    return whitening @ inverse @ np.swapaxes(inverse, 1, 2) @ np.swapaxes(whitening, 1, 2)
