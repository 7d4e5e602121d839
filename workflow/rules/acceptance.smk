# Stage 4b: the validation set as the acceptance test per campaign and sensor, read after every
# choice (the paper's fit, the loop closure's effects and refit): each model's posterior predictive
# check of the validation errors, a verdict, and the diagnosis of a failure.


rule acceptance:
    input:
        campaign=campaign_files,
        registration=rules.prepare.output.registration,
        laplace=rules.prepare.output.laplace,
        paper_samples=f"{SENSOR}/{layout.DEFAULT_SAMPLES}",
        loop=rules.loop_closure.output.report,
        loop_samples=rules.loop_closure.output.samples,
        gp=rules.loop_closure.output.gp,
    output:
        report=f"{SENSOR}/{layout.ACCEPTANCE}",
    log:
        f"{RESULTS}/logs/{{campaign}}/{{sensor}}/acceptance.log",
    resources:
        mem_mb=campaign_mem_mb,
        runtime=runtime_minutes(1, at_least=5),
    params:
        settings=config["acceptance"],
        seed=config["seed"],
    script:
        "../scripts/acceptance.py"
