"""``PickPlaceParallelVectorEnv``: many ``PickPlaceParallel`` lines stepped in one compiled
call (the multi-agent mode of the compiled vector env)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
from gymnasium import spaces

from pnp_twin.learning.envs.common import ObservationView
from pnp_twin.learning.envs.pz_aec import agent_name
from pnp_twin.learning.envs.vector_env import PickPlaceVectorEnv
from pnp_twin.twin.camera import BeltCamera
from pnp_twin.twin.scenario import Scenario


class PickPlaceParallelVectorEnv:
    """``num_envs`` copies of :class:`~pnp_twin.learning.envs.pz_parallel.PickPlaceParallel`
    on the compiled engine, stepped together in one call, every array batched over envs
    and agents (robots, upstream first: agent ``robot_{i+1}`` is column i).

    Step for step it gives what ``num_envs`` ``PickPlaceParallel`` envs with the same
    arguments give for the same seeds and actions (tested in
    ``tests/learning/test_vector_marl.py``), in the layout multi-agent trainers batch:

    - ``reset(seed=s)`` -> ``(obs, info)``; ``step(actions)`` with ``actions`` an integer
      array ``(num_envs, agents)`` of rule indices -> ``(obs, rewards, terminated,
      truncated, info)``.
    - ``obs``: each agent's workspace window, ``(num_envs, agents, C, H, w)`` uint8
      (``single_observation_space``; (1, 8, 7) per agent on paper_baseline);
      :meth:`state`: the global state for centralised critics, the whole belt image
      ``(num_envs, C, H, W)`` (``state_space``).
    - ``rewards``: ``(num_envs, agents)``, each agent's eq. 1 + eq. 2 of its options that
      ended during the step; with ``team_reward=True`` every agent gets their sum.
      :attr:`team_rewards` (num_envs,) is always that sum.
    - ``terminated`` / ``truncated``: ``(num_envs,)`` (all agents of a line end together).
    - ``info``: ``PickPlaceParallel``'s keys as arrays: per agent ``(num_envs, agents)``
      ``deciding`` ("who decides": its robot is free at the new epoch, its action will be
      used), ``picks``, ``noops``, ``option_time``, ``candidates``; ``action_mask``
      ``(num_envs, agents, K)`` int8; per line ``(num_envs,)`` ``tau``, ``time``,
      ``skipped``, ``gripping_rate``, ``line_seed``.
    - Autoreset as :class:`~pnp_twin.learning.envs.vector_env.PickPlaceVectorEnv`
      (Gymnasium's NEXT_STEP: the step after a line's episode ended resets it, ignores its
      actions and returns its first observation with rewards 0, not ended).
    - Seeds: line e is seeded with ``s + e`` as a ``PickPlaceParallel`` reset with that seed
      would be; ``options={"line_seed": k}`` runs line seed ``k`` everywhere.

    Arguments: ``num_envs``, ``scenario``, ``threads`` and the options of
    :class:`~pnp_twin.learning.envs.options.EnvOptions` (``termination`` defaults to
    ``t_all``, as ``PickPlaceParallel``; ``t_continue`` is the asynchronous set-up, one or
    a few agents deciding per step; ``max_cycles`` is a step cap here).
    """

    def __init__(
        self,
        num_envs: int = 1,
        scenario: str | Path | Scenario = "paper_baseline",
        *,
        threads: int | None = None,
        **options: Any,
    ) -> None:
        options.setdefault("termination", "t_all")
        self.team_reward = bool(options.get("team_reward", False))
        self.inner = PickPlaceVectorEnv(
            num_envs,
            scenario,
            action_type="multidiscrete",
            copy=False,
            threads=threads,
            **options,
        )
        inner = self.inner
        self.num_envs = n = inner.num_envs
        self.n_agents = r = inner.n_robots
        self.rules = inner.rules
        self.scenario = inner.scenario
        self.possible_agents = [agent_name(i) for i in range(r)]
        camera = BeltCamera(self.scenario, inner.batch.shape[0])
        c, h, width = camera.shape
        self.window_width = w = camera.window_width
        self._starts = list(camera.starts)
        self._widths = [max(0, min(w, width - s)) for s in self._starts]
        self._windows = np.zeros((n, r, c, h, w), dtype=np.uint8)
        self.view = ObservationView(inner.options.observation, (c, h, w))
        self.single_observation_space = self.view.space
        self.single_action_space: spaces.Discrete = spaces.Discrete(len(self.rules))
        self.state_space = spaces.Box(0, 1, (c, h, width), dtype=np.uint8)
        self.team_rewards = np.zeros(n)

    # -- the API ----------------------------------------------------------------------------
    def reset(
        self, *, seed: int | list[int | None] | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        _obs, info = self.inner.reset(seed=seed, options=options)
        self.team_rewards[:] = 0.0
        return self._observations(), self._info(info)

    def step(
        self, actions: Any
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        _obs, _r, term, trunc, info = self.inner.step(actions)
        rewards = self.inner.batch.rewards.copy()
        rewards[self.inner.last_reset] = 0.0  # lines started afresh: no reward
        self.team_rewards = rewards.sum(axis=1)
        if self.team_reward:
            rewards = np.repeat(self.team_rewards[:, None], self.n_agents, axis=1)
        return self._observations(), rewards, term, trunc, self._info(info)

    def state(self) -> np.ndarray:
        """The whole belt image of every line, (num_envs, C, H, W) uint8 (a copy)."""
        return self.inner.batch.obs.copy()

    def close(self) -> None:
        """Nothing to release."""

    # -- helpers ----------------------------------------------------------------------------
    def _observations(self) -> np.ndarray:
        belt = self.inner.batch.obs
        out = self._windows
        for i, (s, k) in enumerate(zip(self._starts, self._widths, strict=True)):
            out[:, i, :, :, :k] = belt[:, :, :, s : s + k]
        view = self.view
        if view.image:
            s = view.scale
            return out.repeat(s, axis=3).repeat(s, axis=4) * np.uint8(255)
        return out.copy()

    def _info(self, info: dict[str, Any]) -> dict[str, Any]:
        return {k: v for k, v in info.items() if not k.startswith("_")}
