"""The calibration of one sensor in the robot's own terms: calibrated URDFs, the effects a URDF cannot hold, controller offsets."""

from remaster import io
from remaster.analysis import calibrated

w = snakemake.wildcards  # noqa: F821 (snakemake injects it)
with io.log_to(snakemake.log[0]):  # noqa: F821
    i, out = snakemake.input, snakemake.output  # noqa: F821
    files = calibrated.calibrated_stage(io.read_campaign(io.campaign_folder(snakemake.input.campaign)), w.sensor,  # noqa: F821
                                        io.read_csv(i.summary), io.read_loop(i.loop), label=i.loop)
    io.write_text(out.paper, files.paper_urdf)
    io.write_text(out.loop, files.loop_urdf)
    io.write_yaml(out.effects, files.effects)
    io.write_csv(out.offsets, files.offsets)
