"""The synchronous multi-agent environment: PettingZoo Parallel, one agent per robot."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from gymnasium import spaces
from pettingzoo import ParallelEnv

from pnp_twin.learning.envs.common import (
    EpisodeLimits,
    ObservationView,
    check_render_mode,
    line_seed,
    render_line,
)
from pnp_twin.learning.envs.driver import EnvError, EpochDriver, is_rule_index
from pnp_twin.learning.envs.pz_aec import agent_name
from pnp_twin.learning.envs.render import RENDER_FPS, RENDER_MODES
from pnp_twin.policies.rules import PAPER_RULES
from pnp_twin.twin.scenario import Scenario


class PickPlaceParallel(ParallelEnv[str, np.ndarray, int]):
    """Every robot an agent; all agents act at each decision epoch (synchronous decisions).

    Meant for the synchronous schemes: ``t_all`` (default; every available robot is free at
    each epoch, so every agent's action is used) and ``t_any`` (the first free robot
    interrupts the others' approaches; robots carrying a part finish placing and join a
    later epoch). Every live agent passes an action each step; an agent whose robot is not
    free at the epoch (placing under t_any, broken down, or any busy robot under
    ``t_continue``) simply keeps its current option and its action is ignored:
    ``infos[agent]["deciding"]`` says whose actions the next step will use.

    ## Agents, action and observation spaces
    As :class:`~pnp_twin.learning.envs.pz_aec.PickPlaceAEC`: ``robot_1`` .. ``robot_N`` upstream
    first;
    ``Discrete(K)`` rule index; the robot's workspace window ``Box(0, 1, (C, H, w), uint8)``;
    :meth:`state` the whole belt image.

    ## Rewards
    An agent whose option ended at the new epoch gets ``w_e * R_e + w_i * R_i`` (eq. 1:
    picks per second of the option, 0 if none; eq. 2: ``-noop_penalty`` for a NooP); the
    others get 0 that step.

    ## Info
    Per agent: ``tau`` the simulated seconds of the step (under t_all also the duration of
    every option that ended), ``option_time`` the duration of its option that ended (0.0 if
    none did), ``picks`` its grips during the step, ``deciding`` whether it is free at the
    new epoch, ``time`` and ``gripping_rate`` (percent, so far).

    ## Episode end
    All agents terminate when the simulated time reaches the scenario's ``duration``; all
    are truncated after ``max_episode_steps`` steps or at the first epoch after
    ``max_episode_time`` simulated seconds (None: no cap, the default; a directly built
    env, like the Gymnasium one, ends at ``duration`` unless capped). Options still running
    then earn nothing. Stepping after the end raises :class:`EnvError`; call ``reset()``.

    ## Seeds
    ``reset(seed=s)`` seeds the generator that draws the line's seed;
    ``reset(options={"line_seed": k})`` runs the part stream of ``pnp-twin run --seed k``.

    ## Rendering and copies
    ``render_mode`` ``"rgb_array"`` (the top view of the line) or ``"ansi"`` (the belt grid
    as text), at ``metadata["render_fps"]``; ``copy.deepcopy`` and ``pickle`` replay the seed
    and the actions, so a copy continues exactly as the original. ``observation="image"``
    gives 0/255 windows upscaled to sides of at least 36 pixels (see ``PickPlaceEnv``).
    ``agents`` is empty once the episode is over.

    ## Arguments
    ``scenario``, ``overrides``, ``termination`` (default ``t_all``), ``rules``,
    ``reward_weights``, ``noop_penalty``, ``channels``, ``max_episode_steps``: as for
    :class:`~pnp_twin.learning.envs.gym_env.PickPlaceEnv`.

    ## Version history
    - v0: initial version.
    """

    metadata = {
        "name": "pnp_twin_pickplace_parallel_v0",
        "render_modes": RENDER_MODES,
        "render_fps": RENDER_FPS,
    }

    def __init__(
        self,
        scenario: str | Path | Scenario = "paper_baseline",
        overrides: Mapping[str, Any] | None = None,
        termination: str | None = "t_all",
        rules: Sequence[str] = PAPER_RULES,
        reward_weights: tuple[float, float] = (1.0, 1.0),
        noop_penalty: float = 0.01,
        channels: int = 1,
        max_episode_steps: int | None = None,
        max_episode_time: float | None = None,
        observation: str = "grid",
        render_mode: str | None = None,
    ) -> None:
        self.limits = EpisodeLimits.check(max_episode_steps, max_episode_time)
        self.render_mode = check_render_mode(render_mode, RENDER_MODES)
        self.driver = EpochDriver(
            scenario, termination=termination, rules=rules, channels=channels, overrides=overrides
        )
        self.scenario = self.driver.scenario
        self.rules = self.driver.rules
        self.reward_weights = (float(reward_weights[0]), float(reward_weights[1]))
        self.noop_penalty = float(noop_penalty)
        self.max_episode_steps = max_episode_steps
        self.possible_agents = [agent_name(r) for r in range(self.driver.n_robots)]
        camera = self.driver.camera
        self.view = ObservationView(observation, camera.window_shape)
        self._observation_space = self.view.space
        self._action_space: spaces.Discrete = spaces.Discrete(len(self.rules))
        self.state_space = spaces.Box(0, 1, camera.shape, dtype=np.uint8)
        self.agents: list[str] = []
        self._seed_rng = np.random.default_rng()

    def observation_space(self, agent: str) -> spaces.Space[Any]:
        return self._observation_space

    def action_space(self, agent: str) -> spaces.Space[Any]:
        return self._action_space

    def reset(
        self, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[dict[str, np.ndarray], dict[str, dict[str, Any]]]:
        if seed is not None:
            self._seed_rng = np.random.default_rng(seed)
        self.driver.reset(line_seed(self._seed_rng, options))
        self.agents = list(self.possible_agents)
        return self._observations(), self._infos(0.0)

    def step(
        self, actions: dict[str, int]
    ) -> tuple[
        dict[str, np.ndarray],
        dict[str, float],
        dict[str, bool],
        dict[str, bool],
        dict[str, dict[str, Any]],
    ]:
        if not self.agents:
            raise EnvError("step: the episode is over (or not started); call reset()")
        driver = self.driver
        before = driver.now
        chosen: dict[int, int] = {}
        for r in driver.deciding:
            action = actions.get(self.possible_agents[r])
            if action is None:
                continue
            if not is_rule_index(action, len(self.rules)):
                raise EnvError(
                    f"action: {action!r} for {self.possible_agents[r]} is not in "
                    f"0..{len(self.rules) - 1}"
                )
            chosen[r] = int(action)
        driver.act(chosen)
        weights, penalty = self.reward_weights, self.noop_penalty
        rewards = {a: driver.reward(r, weights, penalty) for r, a in enumerate(self.agents)}
        terminated = driver.done
        truncated = not terminated and self.limits.reached(driver.steps, driver.now)
        observations, infos = self._observations(), self._infos(driver.now - before)
        terminations = dict.fromkeys(self.agents, terminated)
        truncations = dict.fromkeys(self.agents, truncated)
        if terminated or truncated:
            self.agents = []
        return observations, rewards, terminations, truncations, infos

    def _observations(self) -> dict[str, np.ndarray]:
        observe = self.driver.observe
        view = self.view
        return {a: view(observe(r)) for r, a in enumerate(self.possible_agents)}

    def _infos(self, tau: float) -> dict[str, dict[str, Any]]:
        driver = self.driver
        deciding = set(driver.deciding)
        picks = driver.step_picks
        now, rate = driver.now, driver.gripping_rate()
        out = {}
        for r, a in enumerate(self.possible_agents):
            option = driver.option(r) if r in deciding else None
            out[a] = {
                "tau": tau,
                "option_time": 0.0 if option is None else option.duration,
                "picks": picks[r],
                "deciding": r in deciding,
                "time": now,
                "gripping_rate": rate,
            }
        return out

    def state(self) -> np.ndarray:
        return self.driver.observe(None)

    def render(self) -> np.ndarray | str | None:  # type: ignore[override]
        """The frame of ``render_mode``: ``rgb_array`` the top view of the line, ``ansi`` the
        belt grid as text (:mod:`pnp_twin.learning.envs.render`); None without a mode."""
        return render_line(self.driver, self.render_mode)

    def close(self) -> None:
        """Nothing to release."""
