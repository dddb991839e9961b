"""The environments' options and their defaults, in one place.

Every environment (:class:`~pnp_twin.learning.envs.gym_env.PickPlaceEnv`, the PettingZoo
:class:`~pnp_twin.learning.envs.pz_aec.PickPlaceAEC` and
:class:`~pnp_twin.learning.envs.pz_parallel.PickPlaceParallel`, the compiled
:class:`~pnp_twin.learning.envs.vector_env.PickPlaceVectorEnv`) takes the same keyword
arguments, the fields of :class:`EnvOptions`; the HDQN trainer reads its reward defaults from
here too. Only ``termination`` has a default per environment (the scenario's for the
single-agent envs, ``t_continue`` for AEC, ``t_all`` for Parallel).

>>> EnvOptions.make(noop_penalty=0.05).noop_penalty
0.05
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, fields, replace
from pathlib import Path
from typing import Any

from pnp_twin.learning.envs.defaults import NOOP_PENALTY, REWARD_WEIGHTS
from pnp_twin.learning.envs.driver import EnvError
from pnp_twin.policies.rules import PAPER_RULES
from pnp_twin.twin.scenario import Scenario

OBSERVATIONS = ("grid", "image")
__all__ = ["NOOP_PENALTY", "OBSERVATIONS", "REWARD_WEIGHTS", "EnvOptions", "env_options"]


@dataclass(frozen=True)
class EnvOptions:
    """What an environment is built from (the keyword arguments of every env class).

    - ``scenario``: a Scenario, a scenario file path or a shipped name.
    - ``overrides``: dotted-path scenario overrides, e.g. ``{"feeder.rate": 12}``.
    - ``termination``: ``t_continue`` | ``t_all`` | ``t_any``; None: the env's default.
    - ``rules``: the rule names an action index refers to (the paper's five by default).
    - ``reward_weights``: (extrinsic, intrinsic) weights of eq. 1 and eq. 2.
    - ``noop_penalty``: eq. 2's penalty per NooP.
    - ``team_reward``: multi-agent envs: every agent gets the sum of all agents' rewards of
      the step (the single-agent envs' reward is that sum already).
    - ``channels``: observation channels, 1 to 3.
    - ``max_episode_steps``: truncation after this many env steps (None: none).
    - ``max_cycles``: PettingZoo's name for the same cap; in the AEC env it caps each
      agent's own decisions (see ``PickPlaceAEC``). Give one of the two.
    - ``max_episode_time``: truncation at the first epoch at or after this many simulated
      seconds (None: none).
    - ``observation``: ``"grid"`` (0/1 cells) or ``"image"`` (0/255, upscaled to >= 36 px).
    - ``skip_noops``: advance past decision epochs where no deciding robot has a candidate
      part (every action gives a NooP there): the env only stops where a choice matters;
      the skipped time is in ``info["tau"]``, the skipped rewards in the step's reward.
    - ``mask_in_observation``: PettingZoo envs: observations are dicts
      ``{"observation": ..., "action_mask": ...}`` (PettingZoo's convention for masks in
      the observation); the mask is always in ``info["action_mask"]`` too.
    """

    scenario: str | Path | Scenario = "paper_baseline"
    overrides: Mapping[str, Any] | None = None
    termination: str | None = None
    rules: tuple[str, ...] = tuple(PAPER_RULES)
    reward_weights: tuple[float, float] = REWARD_WEIGHTS
    noop_penalty: float = NOOP_PENALTY
    team_reward: bool = False
    channels: int = 1
    max_episode_steps: int | None = None
    max_cycles: int | None = None
    max_episode_time: float | None = None
    observation: str = "grid"
    skip_noops: bool = False
    mask_in_observation: bool = False

    @classmethod
    def names(cls) -> tuple[str, ...]:
        """The option names (the envs' keyword arguments)."""
        return tuple(f.name for f in fields(cls))

    @classmethod
    def make(cls, base: EnvOptions | None = None, **kwargs: Any) -> EnvOptions:
        """Options from keyword arguments (over ``base``), checked; an unknown name or a bad
        value is one :class:`EnvError` line naming it."""
        known = cls.names()
        for name in kwargs:
            if name not in known:
                raise EnvError(f"{name}: not an environment option; allowed {', '.join(known)}")
        opts = replace(base or cls(), **kwargs)
        return opts.checked()

    def checked(self) -> EnvOptions:
        """These options with their values normalised (tuples, floats), or EnvError."""
        w = tuple(self.reward_weights)
        if len(w) != 2 or not all(isinstance(x, int | float) and math.isfinite(x) for x in w):
            raise EnvError("reward_weights: give two finite numbers (extrinsic, intrinsic)")
        if not math.isfinite(float(self.noop_penalty)):
            raise EnvError(f"noop_penalty: {self.noop_penalty!r}; give a finite number")
        if self.observation not in OBSERVATIONS:
            raise EnvError(
                f"observation: {self.observation!r} is not allowed; use one of "
                f"{', '.join(OBSERVATIONS)}"
            )
        steps, cycles = self.max_episode_steps, self.max_cycles
        if steps is not None and cycles is not None:
            raise EnvError("max_cycles: give max_cycles or max_episode_steps, not both")
        for name, value in (("max_episode_steps", steps), ("max_cycles", cycles)):
            if value is not None and (isinstance(value, bool) or int(value) != value or value < 1):
                raise EnvError(f"{name}: {value!r} is not allowed; give an integer >= 1")
        time = self.max_episode_time
        if time is not None and not (math.isfinite(time) and time > 0):
            raise EnvError(f"max_episode_time: {time!r} is not allowed; give seconds > 0")
        if isinstance(self.rules, str):
            raise EnvError(f"rules: {self.rules!r}; give a list of rule names")
        return replace(
            self,
            rules=tuple(self.rules),
            reward_weights=(float(w[0]), float(w[1])),
            noop_penalty=float(self.noop_penalty),
            team_reward=bool(self.team_reward),
            skip_noops=bool(self.skip_noops),
            mask_in_observation=bool(self.mask_in_observation),
        )

    @property
    def step_cap(self) -> int | None:
        """The step cap, whichever name gave it."""
        cap = self.max_episode_steps if self.max_episode_steps is not None else self.max_cycles
        return None if cap is None else int(cap)

    def driver_kwargs(self) -> dict[str, Any]:
        """The :class:`~pnp_twin.learning.envs.driver.EpochDriver` arguments."""
        return {
            "scenario": self.scenario,
            "overrides": self.overrides,
            "termination": self.termination,
            "rules": self.rules,
            "channels": self.channels,
            "reward_weights": self.reward_weights,
            "noop_penalty": self.noop_penalty,
        }


def env_options(termination: str | None, kwargs: Mapping[str, Any]) -> EnvOptions:
    """An env's options: ``kwargs`` over the defaults, ``termination`` the env's default
    scheme when the caller gives none."""
    given = dict(kwargs)
    if given.get("termination") is None:
        given["termination"] = termination
    return EnvOptions.make(**given)
