# Stage 4: close the loop per campaign and sensor: diagnose the residual against candidate effects,
# add the supported ones, refit, and report before and after.

LOOP = f"{RESULTS}/{{campaign}}/{{sensor}}/loop_closure"


rule loop_closure:
    input:
        campaign=campaign_files,
        registration=rules.prepare.output.registration,
        laplace=rules.prepare.output.laplace,
    output:
        report=f"{RESULTS}/{{campaign}}/{{sensor}}/loop_closure.json",
        table=f"{LOOP}/before_after.csv",
        signatures=f"{LOOP}/signatures.parquet",
        residuals=f"{LOOP}/residuals.parquet",
        samples=f"{LOOP}/samples.parquet",
        gp=f"{LOOP}/residual_gp.parquet",
    log:
        f"{RESULTS}/logs/{{campaign}}/{{sensor}}/loop_closure.log",
    resources:
        mem_mb=campaign_mem_mb,
        runtime=runtime_minutes(10, at_least=15),
    params:
        settings=config["loop_closure"],
        priors=config["priors"],
        convergence=config["fit"]["cross_check"],
        seed=config["seed"],
    script:
        "../scripts/loop_closure.py"
