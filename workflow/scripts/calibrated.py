"""One sensor's calibration in the robot's own terms: workspace claims, calibrated URDFs, effects,
controller offsets and, for a DH campaign, the calibrated DH tables (and a UR's kinematics_configs)."""

from snakemake.iocontainers import Snakemake

from remaster import api, files, results, seeding
from remaster.calibration import prediction
from remaster.campaigns import folders
from remaster.loop.result import LoopResults

# The job (input, output, params, wildcards, log) that Snakemake's script directive defines before
# this file runs; named here so that readers and linters see where it comes from.
snakemake: Snakemake = globals()["snakemake"]

w, i, out, p = snakemake.wildcards, snakemake.input, snakemake.output, snakemake.params
with files.log_to(snakemake.log[0]):
    read = results.read_results(dict(i.items()), ("summary", "laplace", "loop", "samples", "gp"))
    result = api.stages.make_calibrated_outputs(
        folders.read_campaign(folders.campaign_folder(i.campaign)),
        w.sensor,
        read["summary"],
        read["laplace"],
        LoopResults(read["loop"], read["samples"], read["gp"], i.samples),
        seeding.generator(p.seed, w.campaign, w.sensor, "workspace"),
        prediction.Propagation(p.draws, p.random_configurations, p.seed),
    )
    files.write_csv(out.theoretical, result.workspace.theoretical)
    files.write_csv(out.claims, result.workspace.claims)
    files.write_json(out.workspace, result.workspace.report)
    files.write_text(out.paper, result.files.paper_urdf)
    files.write_text(out.loop, result.files.loop_urdf)
    files.write_text(out.rigid, result.rigid_urdf)
    files.write_text(out.ik, result.ik_urdf)
    files.write_yaml(out.effects, result.files.effects)
    files.write_csv(out.offsets, result.files.offsets)
    if result.dh is not None:
        files.write_yaml(out.paper_dh, result.dh["paper"])
        files.write_yaml(out.loop_dh, result.dh["loop"])
    if result.ur is not None:
        files.write_yaml(out.paper_ur, result.ur["paper"])
        files.write_yaml(out.loop_ur, result.ur["loop"])
