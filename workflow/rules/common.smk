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
