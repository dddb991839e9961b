"""The task suite as BenchMARL tasks, on :func:`~pnp_twin.learning.envs.torchrl_env`.

BenchMARL (``pip install benchmarl``) runs its algorithms (IPPO, MAPPO, IQL, VDN, QMIX,
...) on a task given as a :class:`benchmarl.environments.common.TaskClass`; :func:`task`
builds one for a task of the suite (a name or a versioned id such as ``slow_robot-v1``):

>>> from benchmarl.algorithms import VdnConfig                               # doctest: +SKIP
>>> from benchmarl.experiment import Experiment, ExperimentConfig            # doctest: +SKIP
>>> from benchmarl.models.mlp import MlpConfig                               # doctest: +SKIP
>>> Experiment(task=task("slow_robot-v1"), algorithm_config=VdnConfig.get_from_yaml(),
...            model_config=MlpConfig.get_from_yaml(), seed=0,
...            config=ExperimentConfig.get_from_yaml()).run()                # doctest: +SKIP

The env is the compiled multi-agent vector env with flattened observations: the group
``"agents"`` (one agent per robot) with ``observation``, ``action_mask`` (BenchMARL's
action mask) and ``reward``, the whole belt as ``state`` (for MAPPO's critic and QMIX's
mixer), team rewards (every agent gets the line's picks rate: the cooperative setting VDN
and QMIX assume) and forced NooPs skipped. BenchMARL 1.5.2 pins ``torchrl<0.12``, so it
installs beside torch 2.13 only with torchrl 0.11.1 and tensordict 0.11.0 (docs/marl.md).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from benchmarl.environments.common import TaskClass
from torchrl.data import Composite
from torchrl.envs import EnvBase

from pnp_twin.learning.envs.torchrl_vector import GROUP, torchrl_env
from pnp_twin.learning.tasks import get_task


class PickPlaceTaskClass(TaskClass):  # type: ignore[misc]
    """A task of the suite for BenchMARL; ``config`` holds torchrl_env's keyword arguments
    (``max_steps``: the evaluation rollout's cap, default 3,000 env steps)."""

    def get_env_fun(
        self, num_envs: int, continuous_actions: bool, seed: int | None, device: Any
    ) -> Callable[[], EnvBase]:
        options = {k: v for k, v in self.config.items() if k != "max_steps"}
        options.setdefault("team_reward", True)
        options.setdefault("skip_noops", True)

        def make() -> EnvBase:
            env = torchrl_env(self.name, num_envs, device=device, flatten=True, **options)
            if seed is not None:
                env.set_seed(seed)
            return env

        return make

    def supports_continuous_actions(self) -> bool:
        return False

    def supports_discrete_actions(self) -> bool:
        return True

    def has_render(self, env: EnvBase) -> bool:
        return False

    def max_steps(self, env: EnvBase) -> int:
        return int(self.config.get("max_steps", 3000))

    def group_map(self, env: EnvBase) -> dict[str, list[str]]:
        return dict(env.group_map)

    def observation_spec(self, env: EnvBase) -> Composite:
        spec = env.full_observation_spec_unbatched.clone()
        for key in ("action_mask", "deciding"):
            del spec[GROUP, key]
        for key in ("state", "tau", "gripping_rate"):
            del spec[key]
        return spec

    def info_spec(self, env: EnvBase) -> Composite | None:
        return None

    def state_spec(self, env: EnvBase) -> Composite | None:
        return Composite({"state": env.full_observation_spec_unbatched["state"].clone()})

    def action_mask_spec(self, env: EnvBase) -> Composite | None:
        spec = env.full_observation_spec_unbatched.clone()
        keep = Composite({GROUP: Composite({"action_mask": spec[GROUP, "action_mask"]},
                                           shape=spec[GROUP].shape)})  # fmt: skip
        return keep

    def action_spec(self, env: EnvBase) -> Composite:
        return env.full_action_spec_unbatched

    @staticmethod
    def env_name() -> str:
        return "pnp_twin"


def task(name: str, **config: Any) -> PickPlaceTaskClass:
    """The BenchMARL task of the suite's task ``name`` (``config``: torchrl_env's options,
    e.g. ``overrides={"duration": 120.0}``, and ``max_steps``)."""
    return PickPlaceTaskClass(get_task(name).id, dict(config))


__all__ = ["PickPlaceTaskClass", "task"]
