# Stage 6: the calibration in the robot's own terms: calibrated URDFs, the effects a URDF cannot hold,
# and the controller offsets, per campaign and sensor; two tables per campaign for the report.
from remaster.calibrated import FILES as CALIBRATED_FILES

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
    params:
        folder=lambda wc: f"{RAW}/{wc.campaign}",
    script:
        "../scripts/calibrated.py"


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
    output:
        multiext(f"{TABLES}/calibrated_files", ".csv", ".md", ".tex"),
    log:
        f"{RESULTS}/logs/{{campaign}}/table_calibrated_files.log",
    params:
        sensors=lambda wc: sensors_of(wc.campaign),
        kind="calibrated_files",
    script:
        "../scripts/table_calibrated.py"
