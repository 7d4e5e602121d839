"""The calibration certificate of one campaign: certificate.md, its three tables and certificate.json."""

from pathlib import Path

from remaster import io
from remaster.reporting import certificate, tables

with io.log_to(snakemake.log[0]):  # noqa: F821 (snakemake injects it)
    i, out = snakemake.input, snakemake.output  # noqa: F821
    per_sensor = {
        sensor: certificate.CertificateInputs(
            io.read_laplace(i.laplace[k]), io.read_csv(i.errors[k]), io.read_parquet(i.residuals[k]),
            io.read_csv(i.claims[k]), io.read_json(i.workspace[k]), io.read_loop(i.loop[k]), io.read_csv(i.offsets[k]))
        for k, sensor in enumerate(snakemake.params.sensors)}  # noqa: F821
    cert = certificate.certificate(io.read_json(i.summary), per_sensor)
    for name, table in (("verdict", cert.verdicts), ("accuracy", cert.accuracy), ("corrections", cert.corrections)):
        io.write_table(Path(out[name]).with_suffix(""), table, tables.CAPTIONS[f"certificate_{name}"],
                       f"certificate_{name}")
    io.write_json(out.record, {"campaign": cert.campaign, "heading": cert.heading, "warnings": cert.warnings})
    Path(out.markdown).write_text(certificate.to_markdown(cert), encoding="utf-8", newline="\n")
