"""Posterior samplers against a generic target: nothing here knows about robots.

- `target`: what the samplers take (`Target`, `CallableTarget`) and give (`Chain`), and their error;
- `random_walk`: the random-walk Metropolis core the Metropolis samplers share (a walker advanced
  a block of steps at a time);
- `metropolis`: the paper's Metropolis and the adaptive Gaussian random walk;
- `independence`: independence Metropolis-Hastings with its proposals (a Student-t, a ridge
  that follows a posterior's curved valleys) about a Laplace approximation;
- `chains`: emcee's ensemble, a chain run on, and independent chains run until their
  convergence criteria hold.

Every random draw comes from the `numpy.random.Generator` passed in: the same seed gives
byte-identical chains. The least-squares mode and the paper's Laplace approximation, the
samplers' start, are `inference.least_squares`.
"""
