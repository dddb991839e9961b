"""The multi-agent compiled vector env as a TorchRL ``EnvBase`` (for TorchRL and BenchMARL).

:func:`torchrl_env` wraps :class:`~pnp_twin.learning.envs.vector_marl.PickPlaceParallelVectorEnv`
(``num_envs`` lines stepped in one compiled call) in :class:`PickPlaceTorchRLEnv`, which
follows TorchRL's multi-agent conventions (those of its VMAS and PettingZoo wrappers): the
per-agent entries sit in the group ``"agents"``, batch ``(num_envs, n_agents)``.

- ``("agents", "observation")`` (E, A, C, H, w) float32: the agent's workspace window;
- ``("agents", "action_mask")`` (E, A, K) bool: 1 = the rule is allowed;
- ``("agents", "deciding")`` (E, A) bool: the robot is free, its action counts;
- ``("agents", "action")`` (E, A) int64: a rule index (the action spec, masked);
- ``("agents", "reward")`` (E, A, 1) float32: eq. 1 + eq. 2 (the team's sum with
  ``team_reward=True``);
- ``"state"`` (E, C, H, W) float32: the whole belt (for centralised critics);
- ``"tau"`` (E, 1) float32: the step's simulated seconds (semi-MDP discount ``gamma**tau``);
- ``"gripping_rate"`` (E, 1) float32: G so far, % (the command line's window);
- ``"done"``, ``"terminated"``, ``"truncated"`` (E, 1) bool: a line's agents end together.

The action spec is a :class:`torchrl.data.Categorical` whose mask is the current action mask
(updated at every reset and step), so ``env.rand_step()`` and ``check_env_specs`` draw only
allowed actions; an action outside the mask is accepted (a robot with no candidate does the
same whatever the rule). Lines end at the task's duration (terminated) or a step cap
(truncated); TorchRL resets the lines that ended (``"_reset"``) as its collectors do, and a
line is never autoreset behind TorchRL's back. ``set_seed(s)`` seeds line e with ``s + e``.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import torch
from tensordict import TensorDict, TensorDictBase
from torchrl.data import Bounded, Categorical, Composite, Unbounded
from torchrl.envs import EnvBase

from pnp_twin.learning.envs.vector_marl import PickPlaceParallelVectorEnv
from pnp_twin.twin.scenario import Scenario

GROUP = "agents"


class PickPlaceTorchRLEnv(EnvBase):
    """A TorchRL env over the multi-agent compiled vector env (see the module docstring)."""

    def __init__(
        self, env: PickPlaceParallelVectorEnv, device: str | torch.device = "cpu",
        flatten: bool = False,
    ):  # fmt: skip
        super().__init__(device=device, batch_size=torch.Size([env.num_envs]))
        self.vec = env
        self.flatten = flatten
        """Observations as vectors, (E, A, C*H*w), and the state (E, C*H*W): what MLPs (and
        BenchMARL's models) take."""
        self.n_agents = env.n_agents
        self.rules = tuple(env.rules)
        self.group_map = {GROUP: list(env.possible_agents)}
        self._seed: int | None = None
        self._make_specs()

    # -- specs ------------------------------------------------------------------------------
    def _make_specs(self) -> None:
        e, a, k = self.vec.num_envs, self.n_agents, len(self.rules)
        window = tuple(self.vec.single_observation_space.shape)
        belt = tuple(self.vec.state_space.shape)
        if self.flatten:
            window, belt = (int(np.prod(window)),), (int(np.prod(belt)),)
        high = float(self.vec.single_observation_space.high.max())
        dev = self.device
        self.observation_spec = Composite(
            {
                GROUP: Composite(
                    {
                        "observation": Bounded(
                            0.0, high, shape=(e, a, *window), dtype=torch.float32, device=dev
                        ),
                        "action_mask": _flag((e, a, k), dev),
                        "deciding": _flag((e, a), dev),
                    },
                    shape=(e, a),
                ),
                "state": Bounded(0.0, 1.0, shape=(e, *belt), dtype=torch.float32, device=dev),
                "tau": Unbounded(shape=(e, 1), dtype=torch.float32, device=dev),
                "gripping_rate": Unbounded(shape=(e, 1), dtype=torch.float32, device=dev),
            },
            shape=(e,),
        )
        self.action_spec = Composite(
            {
                GROUP: Composite(
                    {"action": Categorical(k, shape=(e, a), dtype=torch.int64, device=dev)},
                    shape=(e, a),
                )
            },
            shape=(e,),
        )
        self.reward_spec = Composite(
            {
                GROUP: Composite(
                    {"reward": Unbounded(shape=(e, a, 1), dtype=torch.float32, device=dev)},
                    shape=(e, a),
                )
            },
            shape=(e,),
        )
        self.done_spec = Composite(
            {key: _flag((e, 1), dev) for key in ("done", "terminated", "truncated")},
            shape=(e,),
        )

    @property
    def action_key_spec(self) -> Categorical:
        return self.action_spec[GROUP, "action"]  # type: ignore[return-value]

    # -- EnvBase ----------------------------------------------------------------------------
    def _set_seed(self, seed: int | None) -> None:
        self._seed = seed

    def _reset(self, tensordict: TensorDictBase | None = None, **kwargs: Any) -> TensorDictBase:
        e = self.vec.num_envs
        mask = np.ones(e, dtype=bool)
        if tensordict is not None and "_reset" in tensordict.keys():
            mask = tensordict["_reset"].reshape(e).cpu().numpy().astype(bool)
        seed, self._seed = self._seed, None
        options: dict[str, Any] = {"reset_mask": mask}
        obs, info = self.vec.reset(seed=seed, options=options)
        zeros = np.zeros(e, dtype=bool)
        return self._out(obs, info, zeros, zeros, None)

    def _step(self, tensordict: TensorDictBase) -> TensorDictBase:
        action = tensordict[GROUP, "action"].reshape(self.vec.num_envs, self.n_agents)
        obs, rew, term, trunc, info = self.vec.step(action.cpu().numpy())
        # TorchRL resets ended lines itself: undo the vector env's own autoreset
        self.vec.inner._autoreset[:] = False
        return self._out(obs, info, term, trunc, rew)

    # -- helpers ----------------------------------------------------------------------------
    def _out(
        self,
        obs: np.ndarray,
        info: dict[str, Any],
        term: np.ndarray,
        trunc: np.ndarray,
        rewards: np.ndarray | None,
    ) -> TensorDict:
        e, a, dev = self.vec.num_envs, self.n_agents, self.device
        mask = torch.as_tensor(info["action_mask"].astype(bool), device=dev)
        self.action_key_spec.update_mask(mask.clone())
        state = torch.as_tensor(self.vec.state(), dtype=torch.float32, device=dev)
        if self.flatten:
            obs, state = obs.reshape(e, a, -1), state.reshape(e, -1)
        agents: dict[str, torch.Tensor] = {
            "observation": torch.as_tensor(obs, dtype=torch.float32, device=dev),
            "action_mask": mask,
            "deciding": torch.as_tensor(info["deciding"].astype(bool), device=dev),
        }
        if rewards is not None:
            r = torch.as_tensor(rewards, dtype=torch.float32, device=dev)
            agents["reward"] = r.reshape(e, a, 1)
        t = torch.as_tensor(term.astype(bool), device=dev).reshape(e, 1)
        u = torch.as_tensor(trunc.astype(bool), device=dev).reshape(e, 1)
        return TensorDict(
            {
                GROUP: TensorDict(agents, batch_size=(e, a), device=dev),
                "state": state,
                "tau": _column(info["tau"], dev),
                "gripping_rate": _column(info["gripping_rate"], dev),
                "done": t | u,
                "terminated": t,
                "truncated": u,
            },
            batch_size=(e,),
            device=dev,
        )


def _rules(k: int, shape: tuple[int, ...], device: torch.device | str | None) -> Categorical:
    return Categorical(k, shape=shape, dtype=torch.int64, device=device)


def _real(shape: tuple[int, ...], device: torch.device | str | None) -> Unbounded:
    return Unbounded(shape=shape, dtype=torch.float32, device=device)


def _flag(shape: tuple[int, ...], device: torch.device | str | None) -> Categorical:
    return Categorical(2, shape=shape, dtype=torch.bool, device=device)


def _column(values: np.ndarray, device: torch.device | str | None) -> torch.Tensor:
    return torch.as_tensor(np.nan_to_num(np.asarray(values, np.float32)), device=device)[:, None]


def torchrl_env(
    task_or_scenario: str | Path | Scenario = "baseline",
    num_envs: int = 8,
    *,
    device: str | torch.device = "cpu",
    threads: int | None = None,
    flatten: bool = False,
    **options: Any,
) -> PickPlaceTorchRLEnv:
    """A TorchRL env of ``num_envs`` lines of a task (a name of the task suite or a versioned
    id such as ``slow_robot-v1``: its line,
    termination, duration and warm-up) or of a scenario (a shipped name, a file or a
    :class:`Scenario`); ``options`` are :class:`~pnp_twin.learning.envs.options.EnvOptions`'
    (``termination``, ``rules``, ``team_reward``, ``skip_noops``, ``overrides``, ...);
    ``flatten=True`` gives each observation as a vector (for MLPs and BenchMARL)."""
    from pnp_twin.learning.tasks import BY_ID, TASKS, make_env

    name = task_or_scenario if isinstance(task_or_scenario, str) else None
    if name is not None and name.strip().lower() in {**TASKS, **BY_ID}:
        vec = make_env(name, "parallel_vector", num_envs=num_envs, threads=threads, **options)
    else:
        vec = PickPlaceParallelVectorEnv(num_envs, task_or_scenario, threads=threads, **options)
    return PickPlaceTorchRLEnv(vec, device, flatten)


__all__ = ["GROUP", "PickPlaceTorchRLEnv", "torchrl_env"]
