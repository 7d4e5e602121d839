"""The samplers' cross-check (`cross_check`): every method's posterior mean and std per parameter
against the default sampler's, in combined Monte Carlo errors, among the methods that converged and
the least-squares/Laplace solution; and the disagreements it records (`disagreeing`).
"""

from __future__ import annotations

import logging
from collections.abc import Mapping

import numpy as np
import pandas as pd

from .. import diagnostics
from ..files import number_or_nan
from .laplace_report import LaplaceReport
from .model import SIGMA
from .posterior_sampling import chains_of, converged

log = logging.getLogger(__name__)


def cross_check(
    samples: dict[str, pd.DataFrame],
    sampler_reports: Mapping[str, Mapping | None],
    laplace: LaplaceReport,
    tolerance: float,
    max_rhat: float,
    min_ess: float,
    floor: float,
) -> pd.DataFrame:
    """Every method's posterior mean and std per parameter and its disagreement with the default
    sampler in units of combined Monte Carlo error (`diagnostics.cross_check`), as a flat table:
    parameter, then mean_<method>, std_<method>, z_<method>, checked_<method>, disagrees_<method>
    (SI), and `disagreement`: the methods that disagree on the parameter ("" where none does).

    The agreement is checked among the methods that converged by their own diagnostics and the
    least-squares/Laplace solution: disagrees_<method> is True where such a method is more than
    `tolerance` errors from the default sampler (or its z is NaN). A disagreement is marked, not
    raised: the campaign's results and report are made anyway, and the certificate says that the
    fit is not confirmed by a second sampler (`disagreeing`). A method that did not converge (the
    paper's sampler usually: its chain does not travel far enough in 2e5 small steps) is shown
    with its z and checked_<method> False, since its means carry a bias its MCSE does not
    measure. `floor` (fit/cross_check/floor, the one floor of every cross-check): the combined
    error is at least this fraction of the posterior std, because an ESS from chains of a few
    dozen autocorrelation times is itself uncertain; a difference of 0.1 std in a posterior mean is
    far below what the posterior itself leaves uncertain. A method without diagnostics
    counts as not converged.
    """
    names = list(laplace.names) + [SIGMA]
    results = {}
    for method in ("default",) + tuple(m for m in samples if m != "default"):
        results[method] = _moments(samples[method], sampler_reports.get(method), names)
    lap_mean = np.append(laplace.theta_map, laplace.sigma_mean)
    lap_std = np.append(laplace.std, laplace.sigma_std)
    results["laplace"] = (lap_mean, lap_std, np.zeros_like(lap_mean))
    table = diagnostics.cross_check(results, names, tolerance=None, reference="default", floor=floor)
    enforced = ["default", "laplace"] + [
        m for m in samples if m != "default" and converged(sampler_reports.get(m), max_rhat, min_ess)
    ]
    offenders = diagnostics.disagreements(table.loc[:, [c for c in table.columns if c[1] in enforced]], tolerance)
    flat = pd.DataFrame(index=table.index)
    for method in results:
        for quantity in ("mean", "std", "z"):
            flat[f"{quantity}_{method}"] = table[(quantity, method)]
        flat[f"checked_{method}"] = method in enforced
        flat[f"disagrees_{method}"] = [(name, method) in {(o[0], o[1]) for o in offenders} for name in flat.index]
    flat["disagreement"] = [", ".join(o[1] for o in offenders if o[0] == name) for name in flat.index]
    if offenders:
        log.warning(
            "the samplers disagree beyond %g combined Monte Carlo errors (the fit is not confirmed by a second "
            "sampler): %s",
            tolerance,
            "; ".join(f"{name}: {method} vs {reference} (z = {z:+.2f})" for name, method, reference, z in offenders),
        )
    out = flat.reset_index()
    out.attrs["disagreements"] = offenders
    return out


def _moments(samples: pd.DataFrame, report: Mapping | None, names: list[str]) -> tuple[np.ndarray, ...]:
    """(mean, std, mcse), each (P,) over names: the sampler's own diagnostics where they describe
    these samples (`sampler_diagnostics` computed them on the chains its samples file holds, so
    their means agree to rounding), sparing a second pass of the ESS over every chain; else the
    samples' own (a report without a parameter, or of other samples)."""
    rows = {row.get("parameter"): row for row in (report or {}).get("parameters", [])}
    if all(name in rows for name in names):
        mean, std, mcse = (
            np.array([number_or_nan(rows[name].get(quantity)) for name in names])
            for quantity in ("mean", "std", "mcse")
        )
        drawn = samples[names].to_numpy(dtype=float).mean(axis=0)
        with np.errstate(invalid="ignore"):
            agree = (np.abs(mean - drawn) <= 1e-9 * (np.abs(drawn) + std)) | (np.isnan(mean) & np.isnan(drawn))
        if agree.all():
            return mean, std, mcse
    return diagnostics.moments(chains_of(samples, names))


def disagreeing(table: pd.DataFrame) -> dict[str, list[str]]:
    """{parameter: [methods]} on which a `cross_check` table (as made, or read back from
    cross_check.csv) records a disagreement; {} when every checked method agrees."""
    out = {}
    for name, methods in zip(table["parameter"], table["disagreement"]):
        if isinstance(methods, str) and methods.strip():
            out[str(name)] = [m.strip() for m in methods.split(",") if m.strip()]
    return out
