"""TorchRL's ``PettingZooWrapper`` over the SimPy Parallel env, with its action mask.

TorchRL's ``PettingZooWrapper`` (tested with torchrl 0.14.1) takes an action mask from the
observation dict (``mask_in_observation=True``) or from the infos, and removes it from the
place it found it in; but it looks in the observation first and then fails on the infos'
copy of the same mask (``TypeError: 'NoneType' object does not support item assignment`` in
its ``_reset``), and every env of the twin keeps the mask in its infos. :class:`MaskInObservation`
drops the infos' copy, so the wrapper finds the mask once; :func:`pettingzoo_torchrl`
builds the whole stack, its agents in the group ``"agents"`` as in ``torchrl_env``. For
speed, :func:`~pnp_twin.learning.envs.torchrl_vector.torchrl_env`
(the compiled vector env, about a thousand times the steps per second) is the better route.
"""

from __future__ import annotations

from typing import Any

from pettingzoo.utils.wrappers import BaseParallelWrapper
from torchrl.envs.libs.pettingzoo import PettingZooWrapper

from pnp_twin.learning.envs.pz_parallel import PickPlaceParallel


class MaskInObservation(BaseParallelWrapper):  # type: ignore[type-arg]
    """A Parallel env with ``mask_in_observation=True`` whose infos carry no action mask
    (it stays in each observation dict)."""

    def reset(self, seed: int | None = None, options: dict[str, Any] | None = None) -> Any:
        obs, infos = self.env.reset(seed=seed, options=options)
        return obs, _without_mask(infos)

    def step(self, actions: dict[str, int]) -> Any:
        obs, rewards, terms, truncs, infos = self.env.step(actions)
        return obs, rewards, terms, truncs, _without_mask(infos)

    def state(self) -> Any:
        return self.env.state()


def _without_mask(infos: dict[str, dict[str, Any]]) -> dict[str, dict[str, Any]]:
    return {a: {k: v for k, v in i.items() if k != "action_mask"} for a, i in infos.items()}


def pettingzoo_torchrl(**options: Any) -> PettingZooWrapper:
    """TorchRL's ``PettingZooWrapper`` of a :class:`PickPlaceParallel` built with
    ``options`` and the mask in its observations: the mask lands in
    ``("agents", "action_mask")`` and in the action spec."""
    options["mask_in_observation"] = True
    env = MaskInObservation(PickPlaceParallel(**options))
    group = {"agents": list(env.possible_agents)}  # the group torchrl_env names too
    return PettingZooWrapper(env=env, use_mask=True, categorical_actions=True, group_map=group)


__all__ = ["MaskInObservation", "pettingzoo_torchrl"]
