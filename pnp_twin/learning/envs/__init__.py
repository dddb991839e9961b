"""Reinforcement-learning environments over the twin (a front-end: it may import policies).

Importing this package registers ``pnp_twin/PickPlace-v0`` with Gymnasium:

>>> import gymnasium, pnp_twin.learning.envs
>>> env = gymnasium.make("pnp_twin/PickPlace-v0", scenario="paper_baseline")

The PettingZoo environments need the ``learn`` extra (pettingzoo); they are imported lazily.
PettingZoo-style constructors live in :mod:`pnp_twin.learning.envs.pickplace_v0`
(``env()``, ``raw_env()``, ``parallel_env()``).
"""

from __future__ import annotations

from typing import Any

import gymnasium

from pnp_twin.learning.envs.driver import (
    EnvError,
    EpochDriver,
    OptionResult,
    extrinsic_reward,
    intrinsic_reward,
)
from pnp_twin.learning.envs.gym_env import PickPlaceEnv
from pnp_twin.learning.envs.options import EnvOptions
from pnp_twin.twin.camera import CHANNELS, BeltCamera

ENV_ID = "pnp_twin/PickPlace-v0"


class EnvFactory:
    """A picklable env constructor, for vector envs and worker processes."""

    def __init__(self, **kwargs: Any) -> None:
        self.kwargs = kwargs

    def __call__(self) -> PickPlaceEnv:
        return PickPlaceEnv(**self.kwargs)

    def __repr__(self) -> str:
        return f"EnvFactory({self.kwargs!r})"


def make_env(**kwargs: Any) -> EnvFactory:
    """A picklable factory for ``PickPlaceEnv(**kwargs)``, e.g. for AsyncVectorEnv."""
    return EnvFactory(**kwargs)


def __getattr__(name: str) -> Any:
    if name == "PickPlaceAEC":
        from pnp_twin.learning.envs.pz_aec import PickPlaceAEC

        return PickPlaceAEC
    if name == "PickPlaceParallel":
        from pnp_twin.learning.envs.pz_parallel import PickPlaceParallel

        return PickPlaceParallel
    if name == "PickPlaceVectorEnv":
        from pnp_twin.learning.envs.vector_env import PickPlaceVectorEnv

        return PickPlaceVectorEnv
    if name == "PickPlaceParallelVectorEnv":
        from pnp_twin.learning.envs.vector_marl import PickPlaceParallelVectorEnv

        return PickPlaceParallelVectorEnv
    if name in ("torchrl_env", "PickPlaceTorchRLEnv"):  # needs the marl extra (torchrl)
        from pnp_twin.learning.envs import torchrl_vector

        return getattr(torchrl_vector, name)
    raise AttributeError(f"module 'pnp_twin.learning.envs' has no attribute {name!r}")


MAX_EPISODE_STEPS = 5000
"""The paper's cap on decision steps, registered in the spec (Gymnasium's TimeLimit)."""

if ENV_ID not in gymnasium.registry:
    gymnasium.register(
        id=ENV_ID,
        entry_point="pnp_twin.learning.envs.gym_env:PickPlaceEnv",
        vector_entry_point="pnp_twin.learning.envs.vector_env:PickPlaceVectorEnv",
        max_episode_steps=MAX_EPISODE_STEPS,
    )

__all__ = [
    "CHANNELS",
    "ENV_ID",
    "MAX_EPISODE_STEPS",
    "BeltCamera",
    "EnvError",
    "EnvFactory",
    "EnvOptions",
    "EpochDriver",
    "OptionResult",
    "PickPlaceAEC",
    "PickPlaceEnv",
    "PickPlaceParallel",
    "PickPlaceParallelVectorEnv",
    "PickPlaceVectorEnv",
    "extrinsic_reward",
    "intrinsic_reward",
    "make_env",
]
