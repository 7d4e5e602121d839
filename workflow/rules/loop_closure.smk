# Stage 4: close the loop per campaign and sensor: diagnose the residual against candidate effects,
# add the supported ones, refit, and report before and after.

LOOP = f"{SENSOR}/{layout.LOOP}"


rule loop_closure:
    input:
        campaign=campaign_files,
        registration=rules.prepare.output.registration,
        laplace=rules.prepare.output.laplace,
    output:
        report=f"{SENSOR}/{layout.LOOP_CLOSURE}",
        table=f"{SENSOR}/{layout.LOOP_TABLE}",
        signatures=f"{SENSOR}/{layout.LOOP_SIGNATURES}",
        residuals=f"{SENSOR}/{layout.LOOP_RESIDUALS}",
        samples=f"{SENSOR}/{layout.LOOP_SAMPLES}",
        gp=f"{SENSOR}/{layout.LOOP_GP}",
    log:
        f"{RESULTS}/logs/{{campaign}}/{{sensor}}/loop_closure.log",
    resources:
        mem_mb=campaign_mem_mb,
        runtime=runtime_minutes(10, at_least=15),
    params:
        settings=config["loop_closure"],
        priors=config["priors"],
        convergence=config["fit"]["cross_check"],
        outliers=config["outliers"],
        seed=config["seed"],
    script:
        "../scripts/loop_closure.py"
