"""What one sensor's fit gives once its samplers have run: their cross-check, the posterior
summary, the model discrepancy, the remastering (the new zero-offsets for the controller) and the
accuracy metrics of the paper's tables (`accuracy.accuracy_tables`). One job, because each step
needs the one before and none is worth a process of its own."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
import pandas as pd

from ..campaigns.campaign import Campaign
from ..evaluation import accuracy
from ..inference import discrepancy, fit
from ..inference.cross_check import cross_check
from ..inference.laplace_report import LaplaceReport
from ..inference.posterior_summary import posterior_summary, remastering

DEFAULT_METHOD = "default"  # the sampler whose samples every result is made from


@dataclass(frozen=True)
class FitSummary:
    """cross_check: `cross_check.cross_check` table (disagreements marked, not raised); summary: `posterior_summary.posterior_summary` with a parameter
    column; with_discrepancy and discrepancy: `discrepancy.discrepancy_stage`'s table and report;
    remastering: `posterior_summary.remastering`'s JSON-ready content; accuracy: `accuracy.accuracy_tables`."""

    cross_check: pd.DataFrame
    summary: pd.DataFrame
    with_discrepancy: pd.DataFrame
    discrepancy: dict
    remastering: dict
    accuracy: dict


@dataclass(frozen=True)
class SummarySettings:
    """The job's settings: cross_check, the samplers' cross-check (`cross_check.cross_check`'s tolerance,
    max_rhat, min_ess, floor); draws and random_configurations, the accuracy metrics' posterior rows
    and random configurations (`accuracy.accuracy_tables`)."""

    cross_check: Mapping
    draws: int = 2000
    random_configurations: int = 1000


def fit_summary_stage(
    campaign: Campaign,
    sensor: str,
    registration: fit.Registration,
    laplace: LaplaceReport,
    samples: Mapping[str, pd.DataFrame],
    sampler_reports: Mapping[str, dict],
    rng: np.random.Generator,
    settings: SummarySettings,
) -> FitSummary:
    """Cross-check every sampler (`samples`, `sampler_reports`: method -> samples, diagnostics),
    then summarize the default method's samples. A disagreement between the samplers does not stop
    the campaign: the cross-check table marks it (its `disagreement` column; `cross_check.cross_check`),
    every result is made from the default sampler as usual, and the certificate says that the fit
    is not confirmed by a second sampler and on which parameters. The remastering file names the
    campaign by its name (its folder's); rng draws the accuracy metrics' posterior rows, random
    configurations and noise (`accuracy.accuracy_tables`)."""
    checked = cross_check(dict(samples), dict(sampler_reports), laplace, **settings.cross_check)
    summary = posterior_summary(samples[DEFAULT_METHOD], laplace).reset_index()
    with_discrepancy, report = discrepancy.discrepancy_stage(campaign, sensor, registration, laplace, summary)
    corrections = remastering(summary, campaign.chain.joint_names, campaign.name, sensor)
    metrics = accuracy.accuracy_tables(
        campaign,
        sensor,
        registration,
        laplace,
        samples[DEFAULT_METHOD],
        rng,
        n_draws=settings.draws,
        n_random=settings.random_configurations,
    )
    return FitSummary(checked, summary, with_discrepancy, report, corrections, metrics)
