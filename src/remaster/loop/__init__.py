"""The loop closure: what the zero-offsets leave behind, traced to an effect, added on evidence
and cross-validation, and whether the residual is down to the sensor's noise."""
