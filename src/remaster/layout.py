"""Where files lie: a campaign folder's file, the shared robot descriptions, and each stage's results
of one campaign's sensor, as relative POSIX paths. Names only: nothing here touches the disk.

A campaign folder (docs/campaign-format.md) holds CAMPAIGN_FILE and one <sensor>.parquet per sensor.
The workflow writes the results of a campaign's sensor into <results_dir>/SENSOR_FOLDER, at the paths
below (relative to that folder); `remaster predict` and `remaster compensate` read SENSOR_RESULTS
from there. The workflow's rules and the command line take the names from here, so they agree.
A `{method}` in a path is a sampler's name (the workflow's wildcard; `str.format` fills it).
"""

from __future__ import annotations

CAMPAIGN_FILE = "campaign.yaml"
SHARED_ROBOTS = "data/robots"  # under the repository root: URDFs that several campaigns refer to

SENSOR_FOLDER = "{campaign}/{sensor}"  # under results_dir
AUDIT = "audit.json"  # under results_dir: what every result of the run was made from (`remaster.audit`)

# the initial registration and the zero-offset fit (the paper's model)
REGISTRATION = "registration.json"
FIT = "fit"
LAPLACE = f"{FIT}/laplace.json"
SAMPLES = f"{FIT}/samples_{{method}}.parquet"
TRACE = f"{FIT}/trace_{{method}}.parquet"
DIAGNOSTICS = f"{FIT}/diagnostics_{{method}}.json"
CROSS_CHECK = f"{FIT}/cross_check.csv"
SUMMARY = f"{FIT}/summary.csv"  # of the default sampler's samples
DISCREPANCY = f"{FIT}/discrepancy.json"
SUMMARY_DISCREPANCY = f"{FIT}/summary_discrepancy.csv"
DEFAULT_SAMPLES = SAMPLES.format(method="default")
REMASTERING = "remastering.json"

# the loop closure: its report beside the folder of its other files
LOOP_CLOSURE = "loop_closure.json"
LOOP = "loop_closure"
LOOP_TABLE = f"{LOOP}/before_after.csv"
LOOP_SIGNATURES = f"{LOOP}/signatures.parquet"
LOOP_RESIDUALS = f"{LOOP}/residuals.parquet"
LOOP_SAMPLES = f"{LOOP}/samples.parquet"
LOOP_GP = f"{LOOP}/residual_gp.parquet"

# the validation set as the acceptance test, after the loop closure
ACCEPTANCE = "acceptance.json"

# the later stages' folders
METRICS = "metrics"
CALIBRATED = "calibrated"

# the figures (PNG and PDF of each): one sensor's, as <campaign>/figures/<name>_<sensor>, in the order
# they are drawn; and each robot's over its campaigns, as comparison/<name>_<robot>, with the
# comparison table each draws
SENSOR_FIGURES = (
    "zero_offset_trace",
    "zero_offset_histograms",
    "tcp_scatter",
    "post_registration_histograms",
    "loop_signatures",
    "loop_residuals",
    "loop_residual_joints",
    "loop_harmonics",
    "workspace_accuracy",
)
OVER_TIME_FIGURES = {
    "zero_offsets_over_time": "zero_offsets_over_time",
    "loop_effects_over_time": "loop_parameters_over_time",
}

# what `remaster predict` and `remaster compensate` read of a sensor's results, by key
SENSOR_RESULTS = {
    "registration": REGISTRATION,
    "laplace": LAPLACE,
    "summary": SUMMARY,
    "paper_samples": DEFAULT_SAMPLES,
    "loop": LOOP_CLOSURE,
    "loop_samples": LOOP_SAMPLES,
    "gp": LOOP_GP,
}
