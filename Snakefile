# remaster workflow: `snakemake -j2` rebuilds every result from the campaigns in data/raw.
configfile: "config.yaml"


include: "workflow/rules/common.smk"
include: "workflow/rules/campaign.smk"


rule all:
    input:
        expand(f"{RESULTS}/{{campaign}}/campaign/summary.json", campaign=CAMPAIGNS),
    default_target: True
