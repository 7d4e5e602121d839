# Stage 7: across campaigns and sensors, under results/comparison/: zero-offsets and loop-closure
# parameters over time, drift between campaigns of the same robot and the sensors' agreement
# (comparison); each calibration on the other campaigns of its robot (transfer), and drift and
# agreement as the change of predicted marker positions (comparison_prediction); their figures.
from types import SimpleNamespace

from remaster.comparing.comparison import TABLES as COMPARISON_TABLES
from remaster.calibration.prediction import MODELS as TRANSFER_MODELS
from remaster.comparing.predictions import PREDICTION_TABLES
from remaster.layout import OVER_TIME_FIGURES

COMPARISON = f"{RESULTS}/comparison"
PREDICTION_COMPARISON_TABLES = ["transfer", *PREDICTION_TABLES]


ROBOTS = robots()
ALL_CAMPAIGN_FILES = [f for c in CAMPAIGNS for f in campaign_files(SimpleNamespace(campaign=c))]


rule comparison:
    input:
        **{f"metadata__{c}": f"{RAW}/{c}/campaign.yaml" for c in CAMPAIGNS},
        **every_pair_inputs(
            summary=f"{SENSOR}/{layout.SUMMARY_DISCREPANCY}",
            loop=f"{SENSOR}/{layout.LOOP_CLOSURE}",
        ),
    output:
        **{t: multiext(f"{COMPARISON}/{t}", ".csv", ".md", ".tex") for t in COMPARISON_TABLES},
    log:
        f"{RESULTS}/logs/comparison/comparison.log",
    resources:
        mem_mb=2000,
        runtime=10,
    params:
        significance=config["comparison"]["significance"],
    script:
        "../scripts/comparison.py"


rule comparison_prediction:
    input:
        **every_pair_inputs(
            summary=f"{SENSOR}/{layout.SUMMARY}",
            laplace=f"{SENSOR}/{layout.LAPLACE}",
            loop=f"{SENSOR}/{layout.LOOP_CLOSURE}",
            paper_samples=f"{SENSOR}/{layout.DEFAULT_SAMPLES}",
            loop_samples=f"{SENSOR}/{layout.LOOP_SAMPLES}",
        ),
        campaigns=ALL_CAMPAIGN_FILES,
    output:
        **{t: multiext(f"{COMPARISON}/{t}", ".csv", ".md", ".tex") for t in PREDICTION_COMPARISON_TABLES},
    log:
        f"{RESULTS}/logs/comparison/comparison_prediction.log",
    resources:
        mem_mb=4000,
        runtime=30,
    params:
        seed=config["seed"],
        random_configurations=config["comparison"]["random_configurations"],
        draw_pairs=config["comparison"]["draw_pairs"],
    script:
        "../scripts/comparison_prediction.py"


rule comparison_figures:
    input:
        **{t: f"{COMPARISON}/{t}.csv" for t in ["transfer", *OVER_TIME_FIGURES.values()]},
    output:
        **{f"{f}_{r}": multiext(f"{COMPARISON}/{f}_{r}", ".png", ".pdf") for f in OVER_TIME_FIGURES for r in ROBOTS},
        **{
            f"transfer_{m}_{r}": multiext(f"{COMPARISON}/transfer_{m}_{r}", ".png", ".pdf")
            for m in TRANSFER_MODELS
            for r in ROBOTS
        },
    log:
        f"{RESULTS}/logs/comparison/comparison_figures.log",
    resources:
        mem_mb=2000,
        runtime=10,
    params:
        robots=ROBOTS,
        models=list(TRANSFER_MODELS),
    script:
        "../scripts/comparison_figures.py"
