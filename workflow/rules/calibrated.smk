# Stage 6: the calibration in the robot's own terms: calibrated URDFs, the effects a URDF cannot hold,
# the controller offsets and, for a campaign given as a DH table, the calibrated DH tables, per
# campaign and sensor; two tables per campaign for the report.
from remaster.analysis.calibrated import DH_FILES as CALIBRATED_DH_FILES
from remaster.analysis.calibrated import FILES as CALIBRATED_FILES

CALIBRATED = f"{RESULTS}/{{campaign}}/{{sensor}}/calibrated"


rule calibrated:
    input:
        campaign=campaign_files,
        summary=f"{RESULTS}/{{campaign}}/{{sensor}}/fit/summary.csv",
        loop=rules.loop_closure.output.report,
    output:
        paper=f"{CALIBRATED}/paper.urdf",
        loop=f"{CALIBRATED}/loop.urdf",
        effects=f"{CALIBRATED}/loop_effects.yaml",
        offsets=f"{CALIBRATED}/controller_offsets.csv",
    log:
        f"{RESULTS}/logs/{{campaign}}/{{sensor}}/calibrated.log",
    script:
        "../scripts/calibrated.py"


rule calibrated_dh:
    input:
        campaign=campaign_files,
        summary=f"{RESULTS}/{{campaign}}/{{sensor}}/fit/summary.csv",
        loop=rules.loop_closure.output.report,
    output:
        paper=f"{CALIBRATED}/paper_dh.yaml",
        loop=f"{CALIBRATED}/loop_dh.yaml",
    log:
        f"{RESULTS}/logs/{{campaign}}/{{sensor}}/calibrated_dh.log",
    script:
        "../scripts/calibrated_dh.py"


def calibrated_dh_files(wildcards):
    """The calibrated DH tables of a campaign given as a DH table, every sensor; none otherwise."""
    if not gives_dh(wildcards.campaign):
        return []
    return [f"{RESULTS}/{wildcards.campaign}/{s}/calibrated/{name}" for s in sensors_of(wildcards.campaign)
            for name in CALIBRATED_DH_FILES]


rule table_controller_offsets:
    input:
        per_sensor(f"{CALIBRATED}/controller_offsets.csv"),
    output:
        multiext(f"{TABLES}/controller_offsets", ".csv", ".md", ".tex"),
    log:
        f"{RESULTS}/logs/{{campaign}}/table_controller_offsets.log",
    params:
        sensors=lambda wc: sensors_of(wc.campaign),
        kind="controller_offsets",
    script:
        "../scripts/table_calibrated.py"


rule table_calibrated_files:
    input:
        per_sensor(f"{CALIBRATED}/paper.urdf"),
        per_sensor(f"{CALIBRATED}/loop.urdf"),
        per_sensor(f"{CALIBRATED}/loop_effects.yaml"),
        calibrated_dh_files,
    output:
        multiext(f"{TABLES}/calibrated_files", ".csv", ".md", ".tex"),
    log:
        f"{RESULTS}/logs/{{campaign}}/table_calibrated_files.log",
    params:
        sensors=lambda wc: sensors_of(wc.campaign),
        kind="calibrated_files",
        dh=lambda wc: gives_dh(wc.campaign),
    script:
        "../scripts/table_calibrated.py"
