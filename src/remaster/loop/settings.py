"""The loop closure's settings, from the workflow's configuration as its schema has checked it.

Every value comes from the configuration: src/remaster/data/config.schema.yaml is the one place
their defaults live (the workflow fills them in when it validates config.yaml, `remaster.configuration.settings`
for a Python caller), so `settings_from`
requires every key and has no defaults of its own. Only the candidate list is the library's
(`parameter_blocks.EXTENSIONS`), and the prior sets a `priors` section leaves out are `robot.priors.DEFAULTS`.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

from ..inference.parameter_blocks import EXTENSIONS
from ..inference.readings import ModelSettings
from ..robot.priors import Priors, priors_from, with_defaults


@dataclass(frozen=True)
class LoopSettings:
    """candidates: extension blocks to try; min_log_evidence_gain: the Laplace evidence (nats) an
    effect needs; cv_folds, cv_standard_errors: the pose-grouped cross-validation and the number
    of its standard errors the fall must exceed; jackknife_groups: the pose groups of the
    zero-offsets' delete-a-group jackknife (`remaster.loop.jackknife`); model: payload and drift column; priors: the
    extension blocks' Gaussian priors; priors_config: the config's `priors` section, which a
    campaign's own `robot.priors` is laid over; mcmc: {'chains', 'samples', 'burn_in'} of the final
    refit's first attempt, None for Laplace only; convergence: {'max_rhat', 'min_ess',
    'max_doublings'}: the refit's run length doubles until they hold, at most max_doublings times;
    residual_gp: {'subset', 'inducing', 'exact_rows'} of the Gaussian-process candidate tried last
    (`remaster.inference.gp.residual`), None not to try it; closure_level: the closure test's level: the loop is
    closed unless a correct model's held-out error would exceed what is left with at most this
    probability (`remaster.loop.noise_floor`); tracker_noise:
    {'growth_per_m', 'growth_factor'}, the log-normal prior of a laser tracker's range/transverse
    noise model (`remaster.noise`), None not to offer it; gross_errors: {'alpha', 'max_share'} of the
    screen of every row with the final model (`remaster.loop.gross`, from the config's `outliers`);
    harmonic_level: the family-wise level at which a joint's harmonic order is named once
    `joint_harmonics` is added (`remaster.loop.harmonics`; its orders are `model.harmonic_orders`);
    fit_rows: the optimization rows the loop fits at most (a larger set is thinned to every k-th
    pose, `remaster.loop.screened_selection.fitted_rows`)."""

    candidates: tuple[str, ...]
    min_log_evidence_gain: float
    cv_folds: int
    cv_standard_errors: float
    jackknife_groups: int
    model: ModelSettings
    priors: Priors
    priors_config: dict
    mcmc: dict | None
    convergence: dict
    residual_gp: dict | None
    closure_level: float
    tracker_noise: dict | None
    gross_errors: dict
    harmonic_level: float = 0.01
    fit_rows: int = 20000

    def report(self) -> dict:
        """The settings as loop_closure.json records them (JSON-ready)."""
        return {
            "candidates": list(self.candidates),
            "min_log_evidence_gain": self.min_log_evidence_gain,
            "cv_folds": self.cv_folds,
            "cv_standard_errors": self.cv_standard_errors,
            "jackknife_groups": self.jackknife_groups,
            "payload_mass_kg": self.model.payload_mass,
            "payload_com_m": list(self.model.payload_com),
            "drift_column": self.model.drift_column,
            "harmonic_orders": self.model.harmonic_orders,
            "harmonic_level": self.harmonic_level,
            "priors": self.priors.report(),
            "mcmc": self.mcmc,
            "convergence": self.convergence,
            "residual_gp": self.residual_gp,
            "closure_level": self.closure_level,
            "tracker_noise": self.tracker_noise,
            "gross_errors": self.gross_errors,
            "fit_rows": self.fit_rows,
        }


def settings_from(config: Mapping, priors_config: Mapping, convergence: Mapping, outliers: Mapping) -> LoopSettings:
    """LoopSettings from the workflow's `loop_closure` section, its `priors` section, the
    convergence criteria of the fit's cross-check (`fit/cross_check`: max_rhat, min_ess) and the
    `outliers` section (alpha, max_share: the gross-error screen with the final model), as the
    schema has filled them: a missing key is a KeyError (validate the configuration first)."""
    payload = config["payload"]
    priors_config = with_defaults(priors_config)
    return LoopSettings(
        candidates=EXTENSIONS,
        min_log_evidence_gain=float(config["min_log_evidence_gain"]),
        cv_folds=int(config["cv_folds"]),
        cv_standard_errors=float(config["cv_standard_errors"]),
        jackknife_groups=int(config["jackknife_groups"]),
        model=ModelSettings(
            payload_mass=float(payload["mass"]),
            payload_com=tuple(payload["com"]),
            harmonic_orders=int(config["harmonics"]["orders"]),
        ),
        priors=priors_from(priors_config),
        priors_config=dict(priors_config),
        mcmc=dict(config["mcmc"]) if config["mcmc"] else None,
        convergence={
            "max_rhat": convergence["max_rhat"],
            "min_ess": convergence["min_ess"],
            "max_doublings": int(config["max_doublings"]),
        },
        residual_gp=_gp_settings(config["residual_gp"]),
        closure_level=float(config["closure_level"]),
        tracker_noise=_tracker_noise_settings(config["tracker_noise"]),
        gross_errors={"alpha": float(outliers["alpha"]), "max_share": float(outliers["max_share"])},
        harmonic_level=float(config["harmonics"]["level"]),
        fit_rows=int(config["fit_rows"]),
    )


def from_config(config: Mapping) -> LoopSettings:
    """`settings_from` the sections of the whole configuration as the schema has filled it
    (`remaster.configuration.settings`)."""
    return settings_from(config["loop_closure"], config["priors"], config["fit"]["cross_check"], config["outliers"])


def _gp_settings(section: Mapping) -> dict | None:
    """The residual GP's settings from its config section ({'enabled', 'subset', 'inducing', 'exact_rows'})."""
    if not section["enabled"]:
        return None
    return {
        "subset": int(section["subset"]),
        "inducing": int(section["inducing"]),
        "exact_rows": int(section["exact_rows"]),
    }


def _tracker_noise_settings(section: Mapping) -> dict | None:
    """The tracker noise model's prior from its config section ({'enabled', 'growth_per_m', 'growth_factor'})."""
    if not section["enabled"]:
        return None
    return {"growth_per_m": float(section["growth_per_m"]), "growth_factor": float(section["growth_factor"])}
