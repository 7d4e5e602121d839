# Stage 5: across campaigns and sensors: zero-offsets and loop-closure parameters over time, drift
# between campaigns of the same robot, and the sensors' agreement, under results/comparison/.
from remaster.analysis.comparison import LOOP_TABLES, TABLES as COMPARISON_TABLES

COMPARISON = f"{RESULTS}/comparison"
COMPARISON_FIGURES = {"zero_offsets_over_time": "zero_offsets_over_time",
                      "loop_effects_over_time": "loop_parameters_over_time"}  # figure: the table it draws


def comparison_inputs(table):
    """campaign.yaml files and fit summaries with the stds of model discrepancy (`remaster.inference.discrepancy`);
    loop_closure.json files for the loop-closure tables only."""
    return {"metadata": [f"{RAW}/{c}/campaign.yaml" for c in CAMPAIGNS],
            "summaries": every_campaign_sensor(f"{RESULTS}/{{campaign}}/{{sensor}}/fit/summary_discrepancy.csv"),
            "loops": every_campaign_sensor(f"{RESULTS}/{{campaign}}/{{sensor}}/loop_closure.json")
            if table in LOOP_TABLES else []}


for _table in COMPARISON_TABLES:

    rule:
        name:
            f"comparison_{_table}"
        input:
            **comparison_inputs(_table),
        output:
            multiext(f"{COMPARISON}/{_table}", ".csv", ".md", ".tex"),
        log:
            f"{RESULTS}/logs/comparison/{_table}.log",
        params:
            campaigns=CAMPAIGNS,
            pairs=[(c, s) for c in CAMPAIGNS for s in sensors_of(c)],
            table=_table,
            significance=config["comparison"]["significance"],
        script:
            "../scripts/comparison_table.py"


def robots():
    """robot slug -> robot identity, for every robot of the run."""
    from remaster import io
    from remaster.analysis import comparison

    keys = {comparison.robot_identity(io.read_yaml(f"{RAW}/{c}/campaign.yaml")) for c in CAMPAIGNS}
    return {comparison.robot_slug(k): k for k in sorted(keys)}


ROBOTS = robots()


for _figure, _drawn in COMPARISON_FIGURES.items():

    rule:
        name:
            f"comparison_figure_{_figure}"
        input:
            f"{COMPARISON}/{_drawn}.csv",
        output:
            multiext(f"{COMPARISON}/{_figure}_{{robot}}", ".png", ".pdf"),
        log:
            f"{RESULTS}/logs/comparison/{_figure}_{{robot}}.log",
        params:
            identity=lambda wc: ROBOTS[wc.robot],
            figure=_figure,
        script:
            "../scripts/comparison_figure.py"


# Comparison by prediction: each campaign's calibration on the other campaigns of its robot
# (transfer), and drift and agreement as the change of predicted marker positions.
from types import SimpleNamespace

from remaster.analysis.prediction import MODELS as TRANSFER_MODELS, PREDICTION_TABLES

PREDICTION_COMPARISON_TABLES = ["transfer", *PREDICTION_TABLES]


def calibration_inputs(samples):
    """Campaign folders' files, fit summaries, Laplace and loop-closure reports of every (campaign,
    sensor); with `samples`, the posterior samples of both models too."""
    inputs = {"campaigns": [f for c in CAMPAIGNS for f in campaign_files(SimpleNamespace(campaign=c))],
              "summaries": every_campaign_sensor(f"{RESULTS}/{{campaign}}/{{sensor}}/fit/summary.csv"),
              "laplaces": every_campaign_sensor(f"{RESULTS}/{{campaign}}/{{sensor}}/fit/laplace.json"),
              "loops": every_campaign_sensor(f"{RESULTS}/{{campaign}}/{{sensor}}/loop_closure.json")}
    if samples:
        inputs["paper_samples"] = every_campaign_sensor(f"{RESULTS}/{{campaign}}/{{sensor}}/fit/samples_default.parquet")
        inputs["loop_samples"] = every_campaign_sensor(f"{RESULTS}/{{campaign}}/{{sensor}}/loop_closure/samples.parquet")
    return inputs


rule comparison_transfer:
    input:
        **calibration_inputs(samples=False),
    output:
        multiext(f"{COMPARISON}/transfer", ".csv", ".md", ".tex"),
    log:
        f"{RESULTS}/logs/comparison/transfer.log",
    params:
        pairs=[(c, s) for c in CAMPAIGNS for s in sensors_of(c)],
    script:
        "../scripts/comparison_transfer.py"


for _table in PREDICTION_TABLES:

    rule:
        name:
            f"comparison_{_table}"
        input:
            **calibration_inputs(samples=True),
        output:
            multiext(f"{COMPARISON}/{_table}", ".csv", ".md", ".tex"),
        log:
            f"{RESULTS}/logs/comparison/{_table}.log",
        params:
            pairs=[(c, s) for c in CAMPAIGNS for s in sensors_of(c)],
            table=_table,
            seed=config["seed"],
            random_configurations=config["comparison"]["random_configurations"],
            draw_pairs=config["comparison"]["draw_pairs"],
        script:
            "../scripts/comparison_prediction.py"


for _model in TRANSFER_MODELS:

    rule:
        name:
            f"comparison_figure_transfer_{_model}"
        input:
            f"{COMPARISON}/transfer.csv",
        output:
            multiext(f"{COMPARISON}/transfer_{_model}_{{robot}}", ".png", ".pdf"),
        log:
            f"{RESULTS}/logs/comparison/transfer_{_model}_{{robot}}.log",
        params:
            identity=lambda wc: ROBOTS[wc.robot],
            model=_model,
        script:
            "../scripts/comparison_transfer_figure.py"
