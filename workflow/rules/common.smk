# Validates config.yaml against its schema (filling defaults) and lists the campaigns to process.
from pathlib import Path

from snakemake.utils import validate


validate(config, workflow.source_path("../schemas/config.schema.yaml"))

RAW = config["raw_dir"].rstrip("/")
RESULTS = config["results_dir"].rstrip("/")


def list_campaigns():
    if config["campaigns"]:
        missing = [c for c in config["campaigns"] if not Path(RAW, c, "campaign.yaml").is_file()]
        if missing:
            raise ValueError(f"config.yaml: campaigns: no {RAW}/<name>/campaign.yaml for {', '.join(missing)}")
        return list(config["campaigns"])
    return sorted(p.parent.name for p in Path(RAW).glob("*/campaign.yaml"))


CAMPAIGNS = list_campaigns()


def campaign_files(wildcards):
    """Every file of a campaign folder, so that changing one reruns that campaign's jobs only."""
    folder = Path(RAW, wildcards.campaign)
    return sorted(str(p) for p in folder.iterdir() if p.is_file())


def sensors_of(campaign):
    """The sensors of a campaign: its Parquet files (the reader checks they match campaign.yaml)."""
    return sorted(p.stem for p in Path(RAW, campaign).glob("*.parquet"))


def per_sensor(pattern):
    """Input function: `pattern` (with {campaign} and {sensor}) for every sensor of the campaign."""

    def files(wildcards):
        return [pattern.format(campaign=wildcards.campaign, sensor=s) for s in sensors_of(wildcards.campaign)]

    return files


def every_campaign_sensor(pattern):
    """`pattern` for every (campaign, sensor) pair of the run."""
    return [pattern.format(campaign=c, sensor=s) for c in CAMPAIGNS for s in sensors_of(c)]


FIT_METHODS = ["paper", "default", "emcee"]
