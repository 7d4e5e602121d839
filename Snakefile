# remaster workflow: `snakemake -j2` rebuilds every result from the campaigns in data/raw.
configfile: "config.yaml"


include: "workflow/rules/common.smk"
include: "workflow/rules/campaign.smk"
include: "workflow/rules/fit.smk"


rule all:
    input:
        expand(f"{RESULTS}/{{campaign}}/campaign/summary.json", campaign=CAMPAIGNS),
        every_campaign_sensor(f"{RESULTS}/{{campaign}}/{{sensor}}/remastering.json"),
    default_target: True
