"""results/report.html: every table and figure of the run on one self-contained page."""

from pathlib import Path

from remaster import io
from remaster.analysis import prediction
from remaster.reporting import report, tables

with io.log_to(snakemake.log[0]):  # noqa: F821 (snakemake injects it)
    campaigns = {
        name: {"summary": io.read_json(part["summary"]), "certificate": io.read_json(part["certificate"]),
               "tables": {t: io.read_csv(p) for t, p in part["tables"].items()},
               "figures": {f: Path(p).read_bytes() for f, p in part["figures"].items()}}
        for name, part in snakemake.params.layout.items()  # noqa: F821
    }
    layout = snakemake.params.comparison  # noqa: F821
    comparison = {"tables": {t: io.read_csv(p) for t, p in layout["tables"].items()},
                  "figures": {f: Path(p).read_bytes() for f, p in layout["figures"].items()}}
    layout = snakemake.params.prediction  # noqa: F821
    predicted = {"tables": {t: io.read_csv(p) for t, p in layout["tables"].items()},
                 "figures": {f: Path(p).read_bytes() for f, p in layout["figures"].items()}}
    page = report.build(campaigns, {**tables.CAPTIONS, **prediction.CAPTIONS},
                        audit=io.read_json(snakemake.input.audit), comparison=comparison,  # noqa: F821
                        prediction=predicted)
    Path(snakemake.output.html).write_text(page, encoding="utf-8")  # noqa: F821
