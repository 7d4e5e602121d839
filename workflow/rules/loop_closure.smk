# Stage 4: close the loop per campaign and sensor: diagnose the residual against candidate effects,
# add the supported ones, refit, and report before and after.

LOOP = f"{RESULTS}/{{campaign}}/{{sensor}}/loop_closure"


rule loop_closure:
    input:
        campaign=campaign_files,
        registration=rules.registration.output.registration,
        laplace=rules.laplace.output.laplace,
    output:
        report=f"{RESULTS}/{{campaign}}/{{sensor}}/loop_closure.json",
        table=f"{LOOP}/before_after.csv",
        signatures=f"{LOOP}/signatures.parquet",
        residuals=f"{LOOP}/residuals.parquet",
        samples=f"{LOOP}/samples.parquet",
        gp=f"{LOOP}/residual_gp.parquet",
    log:
        f"{RESULTS}/logs/{{campaign}}/{{sensor}}/loop_closure.log",
    params:
        settings=config["loop_closure"],
        priors=config["priors"],
        convergence=config["fit"]["cross_check"],
        seed=config["seed"],
    script:
        "../scripts/loop_closure.py"


rule table_loop_closure:
    input:
        tables=per_sensor(f"{LOOP}/before_after.csv"),
        reports=per_sensor(f"{RESULTS}/{{campaign}}/{{sensor}}/loop_closure.json"),
    output:
        multiext(f"{TABLES}/loop_closure", ".csv", ".md", ".tex"),
    log:
        f"{RESULTS}/logs/{{campaign}}/table_loop_closure.log",
    params:
        sensors=lambda wc: sensors_of(wc.campaign),
        kind="loop_closure",
    script:
        "../scripts/table_loop_closure.py"


rule table_loop_closure_test:
    input:
        tables=per_sensor(f"{LOOP}/before_after.csv"),
        reports=per_sensor(f"{RESULTS}/{{campaign}}/{{sensor}}/loop_closure.json"),
    output:
        multiext(f"{TABLES}/loop_closure_test", ".csv", ".md", ".tex"),
    log:
        f"{RESULTS}/logs/{{campaign}}/table_loop_closure_test.log",
    params:
        sensors=lambda wc: sensors_of(wc.campaign),
        kind="loop_closure_test",
    script:
        "../scripts/table_loop_closure.py"


rule figure_loop_residual_joints:
    input:
        gp=rules.loop_closure.output.gp,
        report=rules.loop_closure.output.report,
    output:
        multiext(f"{FIGURES}/loop_residual_joints_{{sensor}}", ".png", ".pdf"),
    log:
        f"{RESULTS}/logs/{{campaign}}/{{sensor}}/figure_loop_residual_joints.log",
    script:
        "../scripts/figure_loop_residual_joints.py"


rule table_loop_candidates:
    input:
        tables=per_sensor(f"{LOOP}/before_after.csv"),
        reports=per_sensor(f"{RESULTS}/{{campaign}}/{{sensor}}/loop_closure.json"),
    output:
        multiext(f"{TABLES}/loop_candidates", ".csv", ".md", ".tex"),
    log:
        f"{RESULTS}/logs/{{campaign}}/table_loop_candidates.log",
    params:
        sensors=lambda wc: sensors_of(wc.campaign),
        kind="loop_candidates",
    script:
        "../scripts/table_loop_closure.py"


rule figure_loop_signatures:
    input:
        f"{LOOP}/signatures.parquet",
    output:
        multiext(f"{FIGURES}/loop_signatures_{{sensor}}", ".png", ".pdf"),
    log:
        f"{RESULTS}/logs/{{campaign}}/{{sensor}}/figure_loop_signatures.log",
    script:
        "../scripts/figure_loop_signatures.py"


rule figure_loop_residuals:
    input:
        f"{LOOP}/residuals.parquet",
    output:
        multiext(f"{FIGURES}/loop_residuals_{{sensor}}", ".png", ".pdf"),
    log:
        f"{RESULTS}/logs/{{campaign}}/{{sensor}}/figure_loop_residuals.log",
    script:
        "../scripts/figure_loop_residuals.py"


rule loop_workspace:
    input:
        campaign=campaign_files,
        summary=f"{RESULTS}/{{campaign}}/{{sensor}}/fit/summary.csv",
        laplace=rules.laplace.output.laplace,
        report=rules.loop_closure.output.report,
        samples=rules.loop_closure.output.samples,
        gp=rules.loop_closure.output.gp,
    output:
        theoretical=f"{LOOP}/theoretical_accuracy.csv",
        claims=f"{LOOP}/workspace_accuracy.csv",
        report=f"{LOOP}/workspace.json",
    log:
        f"{RESULTS}/logs/{{campaign}}/{{sensor}}/loop_workspace.log",
    params:
        seed=config["seed"],
        draws=config["accuracy"]["draws"],
        random_configurations=config["accuracy"]["random_configurations"],
    script:
        "../scripts/loop_workspace.py"


rule table_workspace:
    input:
        claims=per_sensor(f"{LOOP}/workspace_accuracy.csv"),
        reports=per_sensor(f"{LOOP}/workspace.json"),
    output:
        accuracy=multiext(f"{TABLES}/workspace_accuracy", ".csv", ".md", ".tex"),
        warnings=multiext(f"{TABLES}/workspace_warnings", ".csv", ".md", ".tex"),
    log:
        f"{RESULTS}/logs/{{campaign}}/table_workspace.log",
    params:
        sensors=lambda wc: sensors_of(wc.campaign),
    script:
        "../scripts/table_workspace.py"


rule figure_workspace:
    input:
        f"{LOOP}/workspace_accuracy.csv",
    output:
        multiext(f"{FIGURES}/workspace_accuracy_{{sensor}}", ".png", ".pdf"),
    log:
        f"{RESULTS}/logs/{{campaign}}/{{sensor}}/figure_workspace.log",
    script:
        "../scripts/figure_workspace.py"
