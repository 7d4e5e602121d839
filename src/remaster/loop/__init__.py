"""The loop closure: what the zero-offsets leave behind, traced to an effect, added on evidence
and cross-validation, and whether the residual is down to the sensor's noise.

loop_closure: the stage (`loop_closure_stage`) and its steps in order; settings: its settings from
the configuration; selection: the candidates' fits, scores and the greedy selection; refit: the
MCMC refit and the parameter table; closure: is the loop closed; report: loop_closure.json, typed;
frames: the signatures' and residuals' long tables.
"""
