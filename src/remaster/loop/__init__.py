"""The loop closure: what the zero-offsets leave behind, traced to an effect, added on evidence
and cross-validation, and whether the residual is down to the sensor's noise.

loop_closure: the stage (`loop_closure_stage`) and its steps in order; settings: its settings from
the configuration; selection: the greedy selection, of the candidates (`candidates`) fitted
(`fitted`), scored (`scoring`) over the held-out folds (`held_out`), with its backward pass
(`backward`), the residual GP (`residual_gp`), a tracker's noise shape (`tracker_noise`) and the
link priors' scale (`link_priors`); screened_selection: the selection without the rows its final
model flags as gross errors; refit: the MCMC refit and the parameter table; closure_test: is the
loop closed; result: loop_closure.json, typed; long_tables: the signatures' and residuals' long
tables.
"""
