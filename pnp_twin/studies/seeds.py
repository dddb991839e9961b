"""Replication seeds: common random numbers from one master seed.

Replication k of every grid point and every policy runs with the same seed, so every
comparison between points or policies is paired (same part stream, same failures). The
seeds are child streams of the master seed (``SeedSequence(master).spawn``): child k does
not depend on how many replications are asked for, on the worker count or on the order.
"""

from __future__ import annotations

import numpy as np

SEED_BITS = 53  # exact in float64, so seeds survive CSV, JSON and the report's JavaScript


def replication_seeds(master: int, replications: int) -> list[int]:
    """The run seed of each replication 0..replications-1, derived from ``master``."""
    children = np.random.SeedSequence(master).spawn(replications)
    mask = (1 << SEED_BITS) - 1
    return [int(c.generate_state(1, dtype=np.uint64)[0]) & mask for c in children]


def search_rng(master: int) -> np.random.Generator:
    """The generator of a randomised search (GRASP), independent of the run seeds."""
    return np.random.default_rng(np.random.SeedSequence(master, spawn_key=(1 << 30,)))
