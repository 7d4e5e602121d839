"""Inference: the paper's measurement model and its Bayesian fit (`fit` and the modules it names;
samplers in `sampling`, `least_squares`, identifiability, metrics), the block model and the
extension blocks of the loop closure (`blocks`, `readings`, `parameter_blocks`, `extensions`), their
evidence and the residual GP."""
