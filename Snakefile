# remaster workflow: `snakemake -j2` rebuilds every result from the campaigns in data/raw.
configfile: "config.yaml"


include: "workflow/rules/common.smk"
include: "workflow/rules/campaign.smk"
include: "workflow/rules/fit.smk"
include: "workflow/rules/tables_fit.smk"
include: "workflow/rules/report.smk"


rule all:
    input:
        expand(f"{RESULTS}/{{campaign}}/campaign/summary.json", campaign=CAMPAIGNS),
        every_campaign_sensor(f"{RESULTS}/{{campaign}}/{{sensor}}/remastering.json"),
        expand(f"{RESULTS}/{{campaign}}/tables/{{table}}.md", campaign=CAMPAIGNS,
               table=["zero_offsets", "registration_params"]),
        every_campaign_sensor(f"{RESULTS}/{{campaign}}/figures/zero_offset_trace_{{sensor}}.png"),
        every_campaign_sensor(f"{RESULTS}/{{campaign}}/figures/zero_offset_histograms_{{sensor}}.png"),
        f"{RESULTS}/report.html",
    default_target: True
