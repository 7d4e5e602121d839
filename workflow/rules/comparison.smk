# Stage 5: across campaigns and sensors: zero-offsets over time, drift between campaigns of the
# same robot, and the sensors' agreement, under results/comparison/.

COMPARISON = f"{RESULTS}/comparison"
COMPARISON_TABLES = ["zero_offsets_over_time", "drift_between_campaigns", "sensor_agreement"]


def comparison_inputs():
    return {"metadata": [f"{RAW}/{c}/campaign.yaml" for c in CAMPAIGNS],
            "summaries": every_campaign_sensor(f"{RESULTS}/{{campaign}}/{{sensor}}/fit/summary.csv")}


for _table in COMPARISON_TABLES:

    rule:
        name:
            f"comparison_{_table}"
        input:
            **comparison_inputs(),
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
    from remaster import comparison, io

    keys = {comparison.robot_identity(io.read_yaml(f"{RAW}/{c}/campaign.yaml")) for c in CAMPAIGNS}
    return {comparison.robot_slug(k): k for k in sorted(keys)}


ROBOTS = robots()


rule comparison_figure:
    input:
        f"{COMPARISON}/zero_offsets_over_time.csv",
    output:
        multiext(f"{COMPARISON}/zero_offsets_over_time_{{robot}}", ".png", ".pdf"),
    log:
        f"{RESULTS}/logs/comparison/figure_{{robot}}.log",
    params:
        identity=lambda wc: ROBOTS[wc.robot],
    script:
        "../scripts/comparison_figure.py"
