# remaster workflow: `snakemake -j2` rebuilds every result from the campaigns in data/raw.
configfile: "config.yaml"


include: "workflow/rules/common.smk"
include: "workflow/rules/campaign.smk"
include: "workflow/rules/fit.smk"
include: "workflow/rules/tables_fit.smk"
include: "workflow/rules/accuracy.smk"
include: "workflow/rules/loop_closure.smk"
include: "workflow/rules/comparison.smk"
include: "workflow/rules/calibrated.smk"
include: "workflow/rules/report.smk"


rule all:
    input:
        expand(f"{RESULTS}/{{campaign}}/campaign/summary.json", campaign=CAMPAIGNS),
        every_campaign_sensor(f"{RESULTS}/{{campaign}}/{{sensor}}/remastering.json"),
        expand(f"{RESULTS}/{{campaign}}/tables/{{table}}.md", campaign=CAMPAIGNS,
               table=["zero_offsets", "registration_params"]),
        every_campaign_sensor(f"{RESULTS}/{{campaign}}/figures/zero_offset_trace_{{sensor}}.png"),
        every_campaign_sensor(f"{RESULTS}/{{campaign}}/figures/zero_offset_histograms_{{sensor}}.png"),
        expand(f"{RESULTS}/{{campaign}}/tables/{{table}}.md", campaign=CAMPAIGNS,
               table=list(TABLE_NAMES) + ["sensor_comparison"]),
        expand(f"{RESULTS}/{{campaign}}/tables/{{table}}_vs_paper.md",
               campaign=[c for c in CAMPAIGNS if c in config["paper_twins"]], table=TABLE_NAMES),
        every_campaign_sensor(f"{RESULTS}/{{campaign}}/figures/tcp_scatter_{{sensor}}.png"),
        every_campaign_sensor(f"{RESULTS}/{{campaign}}/figures/post_registration_histograms_{{sensor}}.png"),
        expand(f"{RESULTS}/{{campaign}}/figures/residuals.png", campaign=CAMPAIGNS),
        expand(f"{RESULTS}/{{campaign}}/tables/{{table}}.md", campaign=CAMPAIGNS,
               table=["loop_closure", "loop_closure_test", "loop_candidates", "workspace_accuracy",
                      "workspace_warnings", "controller_offsets", "calibrated_files"]),
        every_campaign_sensor(f"{RESULTS}/{{campaign}}/figures/loop_signatures_{{sensor}}.png"),
        every_campaign_sensor(f"{RESULTS}/{{campaign}}/figures/loop_residuals_{{sensor}}.png"),
        every_campaign_sensor(f"{RESULTS}/{{campaign}}/figures/loop_residual_joints_{{sensor}}.png"),
        every_campaign_sensor(f"{RESULTS}/{{campaign}}/figures/workspace_accuracy_{{sensor}}.png"),
        expand(f"{RESULTS}/comparison/{{table}}.md", table=COMPARISON_TABLES),
        expand(f"{RESULTS}/comparison/{{figure}}_{{robot}}.png", figure=COMPARISON_FIGURES, robot=ROBOTS),
        expand(f"{RESULTS}/comparison/{{table}}.md", table=PREDICTION_COMPARISON_TABLES),
        expand(f"{RESULTS}/comparison/transfer_{{model}}_{{robot}}.png", model=TRANSFER_MODELS, robot=ROBOTS),
        f"{RESULTS}/report.html",
    default_target: True
