# Validates config.yaml against its schema (filling defaults), checks what the schema cannot
# (paths, burn-in shorter than the run) and lists the campaigns to process
# (`remaster.configuration.workflow_run`). Every refusal names the config file(s) and the key
# (docs/bad-input.md).
import os
import re
import subprocess
import sys
import time
from pathlib import Path

from snakemake.utils import validate

from remaster import configuration, files, layout, results
from remaster.campaigns import folders
from remaster.campaigns.robot_model import robot_section

# Snakemake has already loaded the config files, keeping the last of a key given twice: read the YAML
# ones again with remaster's loader, which refuses that (and aliases) naming the file, the key and the
# line. JSON ones are left to Snakemake: a JSON file need not be YAML (tabs).
for configfile in workflow.configfiles:
    if Path(configfile).suffix.lower() != ".json":
        files.read_yaml(configfile)

# the package's schema: the one place the defaults live (`remaster.configuration.settings` reads it too)
validate(config, str(configuration.SCHEMA))

# Each job is single-threaded and -j sets how many run at once. A BLAS that starts a thread per
# core in every job makes two jobs fight for two cores (measured: the loop closure spent 24.6 s of
# CPU for 13.3 s of work). Set before any job starts, so every job inherits it; a value the user
# exported wins.
for variable in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(variable, "1")

# Bytes one job may use: max_job_memory_gb, or this machine's memory shared by the two jobs of -j2.
JOB_MEMORY_LIMIT = (
    config["max_job_memory_gb"] * 1e9
    if config["max_job_memory_gb"] is not None
    else os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES") / 2
)

# what the schema cannot check (paths, burn-ins shorter than their runs) and the run's campaigns,
# each refusal naming the config file(s) in force (or --config) and the key
RAW, RESULTS, CAMPAIGNS = configuration.workflow_run(
    config, " + ".join(str(f) for f in workflow.configfiles) or "config"
)

# a sensor's results folder, `remaster.layout`'s (the command line reads from it): {campaign} and
# {sensor} are the wildcards
SENSOR = f"{RESULTS}/{layout.SENSOR_FOLDER}"


def campaign_files(wildcards):
    """The files a campaign is read from (`folders.campaign_files`: the audit hashes the same), so
    that changing one reruns that campaign's jobs only. A symbolic link that leads to no file (its
    target missing, or a loop) is left out: declared, it would stop graph building for every
    campaign; the campaign's own first job reads the folder and names it."""
    return [str(p) for p in folders.campaign_files(Path(RAW, wildcards.campaign)) if p.exists()]


def sensors_of(campaign):
    """The sensors of a campaign: its Parquet files (the reader checks they match campaign.yaml)."""
    return sorted(p.stem for p in Path(RAW, campaign).glob("*.parquet"))


def gives_dh(campaign):
    """Whether campaign.yaml gives a DH table (robot/dh); a file that does not parse is the campaign
    check's to report, with its file and key."""
    return "dh" in robot_section(Path(RAW, campaign))


def gives_ur_form(campaign):
    """Whether a campaign gets a UR's kinematics_config (`exports.ur_form`): a six-row DH table."""
    dh = robot_section(Path(RAW, campaign)).get("dh")
    return isinstance(dh, dict) and isinstance(dh.get("rows"), list) and len(dh["rows"]) == 6


def sensor_inputs(**patterns):
    """unpack() input function: each named `pattern` (with {campaign} and {sensor}) for every sensor
    of the campaign, named `<name>__<sensor>` (`remaster.stage_inputs` reads them back by name)."""

    def files(wildcards):
        return {
            f"{name}__{sensor}": pattern.format(campaign=wildcards.campaign, sensor=sensor)
            for name, pattern in patterns.items()
            for sensor in sensors_of(wildcards.campaign)
        }

    return files


def every_pair_inputs(**patterns):
    """Named inputs `<name>__<campaign>__<sensor>` for every (campaign, sensor) pair of the run."""
    return {
        f"{name}__{c}__{s}": pattern.format(campaign=c, sensor=s)
        for name, pattern in patterns.items()
        for c in CAMPAIGNS
        for s in sensors_of(c)
    }


def parquet_rows(path):
    """Rows of a Parquet table from its footer; 0 when it does not read: the campaign's first job
    reports the file with the reader's message, and the other campaigns' jobs go on."""
    import pyarrow
    import pyarrow.parquet

    try:
        return pyarrow.parquet.read_metadata(path).num_rows
    except (OSError, pyarrow.ArrowException):
        return 0


def largest_sensor_rows(campaign):
    """Rows of the campaign's largest sensor, from the Parquet footers (no data read)."""
    return max((parquet_rows(p) for p in Path(RAW, campaign).glob("*.parquet")), default=0)


def campaign_mem_mb(wildcards, attempt):
    """Memory (MB) a campaign's job asks for (`remaster.campaigns.capacity.job_request_mb`), more on
    each retry, so a cluster reserves what the job uses."""
    from remaster.campaigns import capacity

    return capacity.job_request_mb(
        largest_sensor_rows(wildcards.campaign),
        config["accuracy"]["draws"],
        attempt,
        config["loop_closure"]["fit_rows"],
    )


def runtime_minutes(minutes_per_thousand_rows, at_least=5):
    """Runtime resource (minutes) of a per-campaign job, growing with the campaign's rows."""

    def runtime(wildcards):
        rows = largest_sensor_rows(wildcards.campaign)
        return max(at_least, int(minutes_per_thousand_rows * rows / 1000) + 1)

    return runtime


FIT_METHODS = ["paper", "default", "emcee"]


# --------------------------------------------------------------------------- for the stages' rules


def one_of(campaigns):
    """A wildcard constraint matching exactly these campaign names (none: matches nothing)."""
    return "|".join(re.escape(c) for c in campaigns) or "(?!)"


def table_files(names):
    """Named outputs: each table as .csv, .md and .tex."""
    return {name: multiext(f"{TABLES}/{name}", ".csv", ".md", ".tex") for name in names}


def calibrated_file_inputs(wildcards):
    """The calibrated files the calibrated-files table lists (DH tables for a DH campaign, the
    kinematics_configs of a UR)."""
    names = [
        *CALIBRATED_FILES,
        *(CALIBRATED_DH_FILES if gives_dh(wildcards.campaign) else ()),
        *(CALIBRATED_UR_FILES if gives_ur_form(wildcards.campaign) else ()),
    ]
    return {
        f"{Path(name).stem}_{Path(name).suffix[1:]}__{s}": f"{RESULTS}/{wildcards.campaign}/{s}/calibrated/{name}"
        for name in names
        for s in sensors_of(wildcards.campaign)
    }


def robots():
    """robot slug -> robot identity, for every robot of the run."""
    from remaster import files
    from remaster import identity
    from remaster.errors import RemasterError

    keys = set()
    for c in CAMPAIGNS:
        # a campaign.yaml that does not read is its own jobs' to report (file, key): the others go on
        try:
            keys.add(identity.robot_identity(files.read_yaml(f"{RAW}/{c}/campaign.yaml")))
        except (RemasterError, OSError, AttributeError, TypeError):
            continue
    return {identity.robot_slug(k): k for k in sorted(keys)}


def report_layout():
    """campaign -> summary, table and figure files, in the order the report shows them."""
    layout = {}
    for c in CAMPAIGNS:
        layout[c] = {
            "summary": f"{RESULTS}/{c}/campaign/summary.json",
            "certificate": f"{RESULTS}/{c}/certificate.json",
            "tables": {
                **{t: f"{RESULTS}/{c}/tables/{t}.csv" for t in REPORT_CERTIFICATE_TABLES},
                **{t: f"{RESULTS}/{c}/tables/{t}.csv" for t in REPORT_TABLES},
                **{
                    f"{t}_vs_paper": f"{RESULTS}/{c}/tables/{t}_vs_paper.csv"
                    for t in TABLE_NAMES
                    if c in config["paper_twins"]
                },
            },
            "figures": {
                **{f"{f}_{s}": f"{RESULTS}/{c}/figures/{f}_{s}.png" for f in SENSOR_FIGURES for s in sensors_of(c)},
                "residuals": f"{RESULTS}/{c}/figures/residuals.png",
            },
        }
    return layout


def audited_results(campaign):
    """Every final result of a campaign: its tables, figures, fits, metrics and remastering files."""
    part = report_layout()[campaign]
    files = [
        part["summary"],
        part["certificate"],
        f"{RESULTS}/{campaign}/certificate.md",
        *part["tables"].values(),
        *part["figures"].values(),
    ]
    files += [str(Path(t).with_suffix(e)) for t in part["tables"].values() for e in (".md", ".tex")]
    files += [str(Path(f).with_suffix(".pdf")) for f in part["figures"].values()]
    for s in sensors_of(campaign):
        base = f"{RESULTS}/{layout.SENSOR_FOLDER.format(campaign=campaign, sensor=s)}"
        names = [
            layout.REMASTERING,
            layout.REGISTRATION,
            layout.SUMMARY,
            layout.LOOP_CLOSURE,
            layout.ACCEPTANCE,
            f"{layout.LOOP}/workspace.json",
            layout.LOOP_GP,
            layout.SUMMARY_DISCREPANCY,
            *[f"{layout.CALIBRATED}/{name}" for name in CALIBRATED_FILES],
            *[f"{layout.CALIBRATED}/{name}" for name in (CALIBRATED_DH_FILES if gives_dh(campaign) else ())],
            layout.DISCREPANCY,
            f"{layout.LOOP}/workspace_accuracy.csv",
            f"{layout.LOOP}/theoretical_accuracy.csv",
            layout.LAPLACE,
            layout.CROSS_CHECK,
            *[layout.SAMPLES.format(method=m) for m in FIT_METHODS],
            *[f"{layout.METRICS}/{n}.csv" for n in ACCURACY_FILES],
        ]
        files += [f"{base}/{name}" for name in names]
    return files


def comparison_layout():
    return {
        "tables": {t: f"{COMPARISON}/{t}.csv" for t in COMPARISON_TABLES},
        "figures": {f"{f}_{r}": f"{COMPARISON}/{f}_{r}.png" for f in OVER_TIME_FIGURES for r in ROBOTS},
    }


def prediction_layout():
    """The transfer table and the comparisons by prediction, with the transfer heat-maps."""
    return {
        "tables": {t: f"{COMPARISON}/{t}.csv" for t in PREDICTION_COMPARISON_TABLES},
        "figures": {f"transfer_{m}_{r}": f"{COMPARISON}/transfer_{m}_{r}.png" for m in TRANSFER_MODELS for r in ROBOTS},
    }


def report_files(wildcards=None):
    files = []
    for part in [*report_layout().values(), comparison_layout(), prediction_layout()]:
        files += [
            *(part[k] for k in ("summary", "certificate") if k in part),
            *part["tables"].values(),
            *part["figures"].values(),
        ]
    return files


RUN = {}  # when this run's jobs started (Snakefile: onstart): a job log older than that is an earlier run's


def report_the_others(failed):
    """After a run in which the campaigns of `failed` ({campaign: what failed}) did not reach their
    results: run the workflow again on the other campaigns, whose results are complete, with
    failed_campaigns set, so that it writes their comparison across campaigns, audit and report,
    the failed campaigns being the report's red rows (its own jobs, logs and provenance: the next
    full run redoes them). Not when every campaign failed, when this run is already that second
    one, or when this run was not asked for the report."""
    others = [c for c in CAMPAIGNS if c not in failed]
    if (
        not failed
        or not others
        or config["failed_campaigns"]
        or "report" not in {j.rule.name for j in workflow.dag.jobs}
    ):
        return
    print(
        f"{', '.join(failed)} failed: writing the report and the comparison across campaigns of "
        f"{', '.join(others)} (the failed campaigns are the report's red rows)"
    )
    settings = files.write_yaml(
        f"{RESULTS}/logs/without_failed/config.yaml",
        {**config, "campaigns": others, "failed_campaigns": dict(failed)},
    )
    # this run still holds Snakemake's lock on the working folder (results_dir has its own lock)
    subprocess.run(
        [sys.executable, "-m", "snakemake", "--snakefile", workflow.main_snakefile, "--nolock"]
        + ["--cores", str(workflow.resource_settings.cores or 1), "--configfile", str(settings)],
        check=False,
    )
