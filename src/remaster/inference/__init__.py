"""Inference: the paper's measurement model and its Bayesian fit (samplers, identifiability,
metrics), the extension blocks of the loop closure, their evidence and the residual GP."""
