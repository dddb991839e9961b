"""The paper's reward constants, the defaults of every env and of the trainer (read through
:class:`~pnp_twin.learning.envs.options.EnvOptions`; a module of their own so that the epoch
driver, which the options module imports, reads the same numbers)."""

from __future__ import annotations

NOOP_PENALTY = 0.01
"""The paper's eq. 2: the reward of a NooP is ``-NOOP_PENALTY``."""
REWARD_WEIGHTS = (1.0, 1.0)
"""Weights of eq. 1 (picks per second of an option) and eq. 2 (the NooP penalty)."""
