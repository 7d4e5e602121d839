"""The Gaussian-process family: one kernel over the joint angles and what is built on it.

- `kernels`: the kernel on the circle of each joint, its hyperparameters and the noise covariance;
- `likelihood`: Gaussian log densities (the exact marginal likelihood with its gradient, independent
  noise, the dense evidence of a linear model under any covariance);
- `residual`: the residual GP over the joint angles (hyperparameter fit, DTC prediction, Titsias' bound);
- `evidence_gain`: the residual GP's evidence against independent noise;
- `loop_candidate`: the residual GP as a candidate of the loop closure (fitted, scored, written, read back);
- `with_parameters`: a parametric model with the GP present, its parameters integrated with it;
- `joint_error`: what the parametric effects leave read as errors of each joint's own angle.
"""
