# Stage 5: the calibration in the robot's own terms, per campaign and sensor: the workspace claims
# (where it holds, both models' posteriors propagated), the calibrated URDFs, the effects a URDF
# cannot hold, the controller offsets and, for a campaign given as a DH table, the calibrated DH
# tables (a UR's also as its kinematics_config). Three rules because the DH tables exist only for DH
# campaigns, the kinematics_configs only for a UR's six-row table: each campaign matches one.
from remaster.calibration.exports import DH_FILES as CALIBRATED_DH_FILES
from remaster.calibration.exports import FILES as CALIBRATED_FILES
from remaster.calibration.exports import UR_FILES as CALIBRATED_UR_FILES

CALIBRATED = f"{SENSOR}/{layout.CALIBRATED}"
DH_CAMPAIGNS = [c for c in CAMPAIGNS if gives_dh(c)]
UR_CAMPAIGNS = [c for c in DH_CAMPAIGNS if gives_ur_form(c)]


CALIBRATED_INPUTS = dict(
    campaign=campaign_files,
    summary=f"{SENSOR}/{layout.SUMMARY}",
    laplace=rules.prepare.output.laplace,
    loop=rules.loop_closure.output.report,
    samples=rules.loop_closure.output.samples,
    gp=rules.loop_closure.output.gp,
)
CALIBRATED_OUTPUTS = dict(
    theoretical=f"{LOOP}/theoretical_accuracy.csv",
    claims=f"{LOOP}/workspace_accuracy.csv",
    workspace=f"{LOOP}/workspace.json",
    paper=f"{CALIBRATED}/paper.urdf",
    loop=f"{CALIBRATED}/loop.urdf",
    rigid=f"{CALIBRATED}/rigid.urdf",
    ik=f"{CALIBRATED}/ik.urdf",
    effects=f"{CALIBRATED}/loop_effects.yaml",
    offsets=f"{CALIBRATED}/controller_offsets.csv",
)
CALIBRATED_PARAMS = dict(
    seed=config["seed"],
    draws=config["accuracy"]["draws"],
    random_configurations=config["accuracy"]["random_configurations"],
)


rule calibrated:
    input:
        **CALIBRATED_INPUTS,
    output:
        **CALIBRATED_OUTPUTS,
    log:
        f"{RESULTS}/logs/{{campaign}}/{{sensor}}/calibrated.log",
    wildcard_constraints:
        campaign=f"(?!(?:{one_of(DH_CAMPAIGNS)})/)[^/]+",
    resources:
        mem_mb=campaign_mem_mb,
        runtime=runtime_minutes(2, at_least=10),
    params:
        **CALIBRATED_PARAMS,
    script:
        "../scripts/calibrated.py"


rule calibrated_dh:
    input:
        **CALIBRATED_INPUTS,
    output:
        **CALIBRATED_OUTPUTS,
        paper_dh=f"{CALIBRATED}/paper_dh.yaml",
        loop_dh=f"{CALIBRATED}/loop_dh.yaml",
    log:
        f"{RESULTS}/logs/{{campaign}}/{{sensor}}/calibrated.log",
    wildcard_constraints:
        campaign=one_of([c for c in DH_CAMPAIGNS if c not in UR_CAMPAIGNS]),
    resources:
        mem_mb=campaign_mem_mb,
        runtime=runtime_minutes(2, at_least=10),
    params:
        **CALIBRATED_PARAMS,
    script:
        "../scripts/calibrated.py"


rule calibrated_ur:
    input:
        **CALIBRATED_INPUTS,
    output:
        **CALIBRATED_OUTPUTS,
        paper_dh=f"{CALIBRATED}/paper_dh.yaml",
        loop_dh=f"{CALIBRATED}/loop_dh.yaml",
        paper_ur=f"{CALIBRATED}/paper_ur_kinematics.yaml",
        loop_ur=f"{CALIBRATED}/loop_ur_kinematics.yaml",
    log:
        f"{RESULTS}/logs/{{campaign}}/{{sensor}}/calibrated.log",
    wildcard_constraints:
        campaign=one_of(UR_CAMPAIGNS),
    resources:
        mem_mb=campaign_mem_mb,
        runtime=runtime_minutes(2, at_least=10),
    params:
        **CALIBRATED_PARAMS,
    script:
        "../scripts/calibrated.py"
