"""Reproducible random generators: one seed from the config, one independent stream per job."""

from __future__ import annotations

import zlib

import numpy as np


def generator(seed: int, *labels: str) -> np.random.Generator:
    """A Generator for the job named by `labels` (campaign, sensor, method, ...): the same seed
    and labels give the same stream on every machine and in any job order, and different labels
    give independent streams."""
    keys = [zlib.crc32(label.encode("utf-8")) for label in labels]
    return np.random.default_rng(np.random.SeedSequence([int(seed), *keys]))
