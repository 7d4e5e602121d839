"""Loop closures computed once per session: `closed` returns the same result object to every test
that asks with the same chain, sensor (the same object: `simulated` campaigns are themselves made
once), settings and seed. Results are read, never changed, by the tests."""

from __future__ import annotations

import numpy as np

from remaster.inference import fit
from remaster.loop import loop_closure

_closed: dict[tuple, tuple] = {}


def closed(chain, sensor, settings, seed: int = 0):
    """The loop after the zero-offset fit's registration and identifiability analysis (`close_loop`),
    memoised on (chain, sensor, settings, seed): the inputs are kept beside the result, so an
    object's id is never reused for another while its result is cached."""
    key = (id(chain), id(sensor), repr(settings), seed)
    hit = _closed.get(key)
    if hit is not None and hit[0] is chain and hit[1] is sensor:
        return hit[2]
    registration = fit.register(chain, sensor)
    _, analysis, _ = fit.build_model(chain, sensor, registration.t_nr)
    result = loop_closure.close_loop(
        chain, sensor, registration.t_nr, analysis.held, np.random.default_rng(seed), settings
    )
    _closed[key] = (chain, sensor, result)
    return result
