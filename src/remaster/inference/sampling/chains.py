"""Running chains: emcee's ensemble (`run_emcee`), a random-walk chain run on (`extend`), and
several independent chains of one sampler (`run_chains`), each run on until its convergence
criteria hold.

Step counts: `n_steps` is the total number of iterations per walker INCLUDING burn-in, so a
chain keeps (n_steps - burn_in) x n_walkers states.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np  # emcee is imported in run_emcee (test_architecture: light readers)

from .random_walk import _check_counts, _gaussian_steps, _Progress, _start, _uniform_steps, _walk, _Walker
from .target import Chain, SamplingError, Target


def run_emcee(
    target: Target,
    rng: np.random.Generator,
    start,
    spread,
    n_walkers: int = 32,
    n_steps: int = 5_000,
    burn_in: int = 1_000,
    enough: Callable[[np.ndarray], bool] | None = None,
    max_doublings: int = 0,
) -> Chain:
    """emcee's affine-invariant ensemble (stretch move), log_prob_many over all walkers per call.

    start (P,) SI; spread (P,) or scalar SI: walkers start at start + spread * N(0, 1), redrawn
    where the log-posterior is -inf (e.g. sigma <= 0). n_steps total per walker including
    burn_in. emcee's own generator is a RandomState seeded from `rng`, so runs are reproducible
    and the global NumPy state is neither used nor changed.

    enough: a test of the kept walkers' paths (n_steps, n_walkers, P), e.g. the convergence
    criteria; while it fails, the same ensemble runs on for as many kept steps again (the run
    doubles), at most max_doublings times. So a run is as long as its criteria need, not longer.
    """
    import emcee

    p = len(target.names)
    if n_walkers < 2 * p:
        raise ValueError(f"emcee needs at least 2P = {2 * p} walkers, got {n_walkers}")
    kept = _check_counts(n_steps, burn_in)
    centre = _start(target, start).theta
    spread = np.broadcast_to(np.asarray(spread, dtype=float), (p,))
    walkers = centre + spread * rng.standard_normal((n_walkers, p))
    for _ in range(100):
        bad = ~np.isfinite(target.log_prob_many(walkers))
        if not bad.any():
            break
        walkers[bad] = centre + spread * rng.standard_normal((int(bad.sum()), p))
    else:
        raise SamplingError(
            f"{int(bad.sum())} of {n_walkers} initial walkers stay outside the support after 100 redraws: reduce spread"
        )
    seed = int(rng.integers(2**32))
    initial = emcee.State(walkers, random_state=np.random.RandomState(seed).get_state())
    sampler = emcee.EnsembleSampler(n_walkers, p, target.log_prob_many, vectorize=True)
    state = sampler.run_mcmc(initial, burn_in, progress=False) if burn_in else initial
    accepted_before = sampler.backend.accepted.copy() if burn_in else np.zeros(n_walkers)
    # the state is emcee's own after burn-in: its walker-independence check is for user starts,
    # and would reject an ensemble still contracting towards a far posterior
    state = sampler.run_mcmc(state, kept, progress=False, skip_initial_state_check=bool(burn_in))
    doublings = 0
    while enough is not None and doublings < max_doublings and not enough(sampler.get_chain(discard=burn_in)):
        state = sampler.run_mcmc(state, kept * 2**doublings, progress=False)
        doublings += 1
    kept *= 2**doublings
    accepted = sampler.backend.accepted - accepted_before
    settings = {
        "n_steps": burn_in + kept,
        "burn_in": burn_in,
        "n_walkers": n_walkers,
        "spread": spread.copy(),
        "doublings": doublings,
    }
    return Chain(
        sampler.get_chain(discard=burn_in, flat=True),
        sampler.get_log_prob(discard=burn_in, flat=True),
        float(accepted.sum() / (kept * n_walkers)),
        tuple(target.names),
        "emcee",
        settings,
        n_walkers=n_walkers,
    )


def extend(
    target: Target,
    rng: np.random.Generator,
    chain: Chain,
    n_steps: int,
    progress: Callable[[int, int, float], None] | None = None,
) -> Chain:
    """`chain` (a random-walk Metropolis chain: the adaptive or the paper's) run on for n_steps
    more steps from its last state with its own proposal, frozen since its burn-in, so the longer
    chain is the same time-homogeneous Markov chain, only longer. settings["n_samples"] counts
    the steps added, settings["doublings"] how many times it was extended."""
    if "proposal_covariance" in chain.settings and chain.method == "metropolis_adaptive":
        draw = _gaussian_steps(np.asarray(chain.settings["proposal_covariance"], dtype=float))
    elif "proposal_half_widths" in chain.settings:
        draw = _uniform_steps(np.asarray(chain.settings["proposal_half_widths"], dtype=float))
    else:
        raise ValueError(f"a {chain.method} chain cannot be extended: only random-walk Metropolis chains can")
    if n_steps < 1:
        raise ValueError(f"n_steps must be at least 1, got {n_steps}")
    walker = _Walker(chain.samples[-1].copy(), float(chain.log_prob[-1]))
    samples, log_probs, accepted = _walk(target, rng, walker, n_steps, draw, True, _Progress(progress, n_steps))
    kept = chain.n_steps
    accepted_before = round(chain.acceptance_rate * kept)  # the rate is a count over kept steps
    settings = {
        **chain.settings,
        "n_samples": chain.settings.get("n_samples", kept) + n_steps,
        "doublings": chain.settings.get("doublings", 0) + 1,
    }
    return Chain(
        np.concatenate([chain.samples, samples]),
        np.concatenate([chain.log_prob, log_probs]),
        (accepted_before + accepted) / (kept + n_steps),
        chain.names,
        chain.method,
        settings,
    )


def run_chains(
    sampler_fn: Callable[..., Chain],
    target: Target,
    rng: np.random.Generator,
    n_chains: int,
    starts,
    *,
    enough: Callable[[list[Chain]], bool] | None = None,
    max_doublings: int = 0,
    **kw,
) -> list[Chain]:
    """n_chains >= 2 independent runs of sampler_fn(target, child_rng, start, **kw).

    starts: (n_chains, P) one start each (overdispersed starts make R-hat meaningful) or (P,)
    shared. Child generators come from rng.spawn, so chain i is the same whatever n_chains.

    enough: a test of the chains together (R-hat needs them all), e.g. the convergence criteria;
    while it fails, every chain runs on (`extend`, its own generator) for as many kept steps
    again, so the kept part doubles, at most max_doublings times (as `run_emcee` does).
    """
    if n_chains < 2:
        raise ValueError(f"run_chains needs n_chains >= 2 for between-chain diagnostics, got {n_chains}")
    starts = np.asarray(starts, dtype=float)
    if starts.ndim == 1:
        starts = np.broadcast_to(starts, (n_chains, len(starts)))
    if len(starts) != n_chains:
        raise ValueError(f"starts has {len(starts)} rows for {n_chains} chains")
    children = rng.spawn(n_chains)
    chains = [sampler_fn(target, child, start, **kw) for child, start in zip(children, starts)]
    doublings = 0
    while enough is not None and doublings < max_doublings and not enough(chains):
        chains = [extend(target, child, c, c.n_steps, kw.get("progress")) for child, c in zip(children, chains)]
        doublings += 1
    return chains
