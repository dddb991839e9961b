"""The synchronous multi-agent environment: PettingZoo Parallel, one agent per robot."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
from gymnasium import spaces
from pettingzoo import ParallelEnv

from pnp_twin.learning.envs.common import (
    EpisodeLimits,
    ObservationView,
    agent_observation_space,
    check_render_mode,
    line_seed,
    render_line,
    rule_mask,
    team,
)
from pnp_twin.learning.envs.driver import EnvError, EpochDriver, is_rule_index
from pnp_twin.learning.envs.options import env_options
from pnp_twin.learning.envs.pz_aec import agent_name
from pnp_twin.learning.envs.render import RENDER_FPS, RENDER_MODES
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
    As :class:`~pnp_twin.learning.envs.pz_aec.PickPlaceAEC`: ``robot_1`` .. ``robot_N``
    upstream first; ``Discrete(K)`` rule index; the robot's workspace window
    ``Box(0, 1, (C, H, w), uint8)`` ((1, 8, 7) on paper_baseline); :meth:`state` the whole
    belt image.

    ## Action masks
    ``infos[agent]["action_mask"]`` (int8 over the K rules; in the observation too with
    ``mask_in_observation=True``, PettingZoo's dict ``{"observation", "action_mask"}``):
    all 1 when the agent's robot decides and has a candidate part, else only rule 0 (its
    action changes nothing: it is not deciding, or every rule gives the same NooP).

    ## Skipping forced NooPs
    With ``skip_noops=True`` a step runs on past the epochs where no deciding robot has a
    candidate: ``infos[agent]["tau"]`` is all the time that passed, ``skipped`` the epochs
    passed, and each agent's reward sums its options that ended in between.

    ## Rewards
    An agent whose option ended during the step gets ``w_e * R_e + w_i * R_i`` (eq. 1:
    picks per second of the option, 0 if none; eq. 2: ``-noop_penalty`` for a NooP); the
    others get 0 that step. With ``team_reward=True`` every agent gets the sum over all
    agents (a shared team reward).

    ## Info
    The keys of every env of this package (see ``PickPlaceEnv``), per agent: ``tau`` the
    simulated seconds of the step (under t_all also the duration of every option that
    ended), ``option_time`` the duration of its option that ended (0.0 if none did),
    ``picks`` and ``noops`` its grips and NooPs during the step, ``deciding`` whether its
    robot is free at the new epoch (its action is used at the next step), ``candidates``,
    ``action_mask``, ``skipped``, ``time``, ``gripping_rate`` (percent over the command
    line's window: parts fed after the warm-up) and ``line_seed``.

    ## Episode end
    All agents terminate when the simulated time reaches the scenario's ``duration``; all
    are truncated after ``max_episode_steps`` (or ``max_cycles``, PettingZoo's name) steps
    or at the first epoch after ``max_episode_time`` simulated seconds (None: no cap, the
    default). Options still running then earn nothing. Stepping after the end raises
    :class:`EnvError`; call ``reset()``.

    ## Seeds
    ``reset(seed=s)`` seeds the generator that draws the line's seed;
    ``reset(options={"line_seed": k})`` runs the part stream of ``pnp-twin run --seed k``.

    ## Rendering and copies
    ``render_mode`` ``"human"`` (the belt grid printed as text), ``"rgb_array"`` (the top
    view of the line) or ``"ansi"`` (the text), at ``metadata["render_fps"]``;
    ``copy.deepcopy`` and ``pickle`` replay the seed and the actions, so a copy continues
    exactly as the original. ``observation="image"`` gives 0/255 windows upscaled to sides
    of at least 36 pixels (see ``PickPlaceEnv``). ``agents`` is empty once the episode is
    over.

    ## Arguments
    ``scenario``, ``render_mode`` and the options of
    :class:`~pnp_twin.learning.envs.options.EnvOptions` (``termination`` defaults to
    ``t_all`` here).

    ## Version history
    - v0: initial version (masks, ``skip_noops``, ``team_reward``, ``max_cycles`` and the
      ``human`` mode added without changing the dynamics).
    """

    metadata = {
        "name": "pnp_twin_pickplace_parallel_v0",
        "render_modes": RENDER_MODES,
        "render_fps": RENDER_FPS,
    }

    def __init__(
        self,
        scenario: str | Path | Scenario = "paper_baseline",
        *,
        render_mode: str | None = None,
        **options: Any,
    ) -> None:
        self.options = opts = env_options("t_all", {"scenario": scenario, **options})
        self.limits = EpisodeLimits.check(opts.step_cap, opts.max_episode_time)
        self.render_mode = check_render_mode(render_mode, RENDER_MODES)
        self.driver = EpochDriver(**opts.driver_kwargs())
        self.scenario = self.driver.scenario
        self.rules = self.driver.rules
        self.reward_weights = opts.reward_weights
        self.noop_penalty = opts.noop_penalty
        self.max_episode_steps = opts.step_cap
        self.possible_agents = [agent_name(r) for r in range(self.driver.n_robots)]
        camera = self.driver.camera
        self.view = ObservationView(opts.observation, camera.window_shape)
        k = len(self.rules)
        self._observation_space = agent_observation_space(self.view, k, opts.mask_in_observation)
        self._action_space: spaces.Discrete = spaces.Discrete(k)
        self.state_space = spaces.Box(0, 1, camera.shape, dtype=np.uint8)
        self.agents: list[str] = []
        self._seed_rng = np.random.default_rng()
        self._steps = 0

    def observation_space(self, agent: str) -> spaces.Space[Any]:
        return self._observation_space

    def action_space(self, agent: str) -> spaces.Space[Any]:
        return self._action_space

    def reset(
        self, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[dict[str, np.ndarray], dict[str, dict[str, Any]]]:
        if seed is not None:
            self._seed_rng = np.random.default_rng(seed)
        driver = self.driver
        driver.reset(line_seed(self._seed_rng, options))
        driver.skip_to_choice(self.options.skip_noops, until=self._until)
        self._steps = 0
        self.agents = list(self.possible_agents)
        return self._observations(), self._infos(driver.now)

    @property
    def _until(self) -> float:
        return math.inf if self.limits.time is None else self.limits.time

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
        driver.act(chosen, self.options.skip_noops, until=self._until)
        self._steps += 1
        got = driver.step_rewards
        rewards = {a: got[r] for r, a in enumerate(self.agents)}
        if self.options.team_reward:
            rewards = team(rewards)
        terminated = driver.done
        truncated = not terminated and self.limits.reached(self._steps, driver.now)
        observations, infos = self._observations(), self._infos(driver.now - before)
        terminations = dict.fromkeys(self.agents, terminated)
        truncations = dict.fromkeys(self.agents, truncated)
        if terminated or truncated:
            self.agents = []
        return observations, rewards, terminations, truncations, infos

    def _observations(self) -> dict[str, Any]:
        observe = self.driver.observe
        view = self.view
        if self.options.mask_in_observation:
            return {
                a: {"observation": view(observe(r)), "action_mask": self._mask(r)}
                for r, a in enumerate(self.possible_agents)
            }
        return {a: view(observe(r)) for r, a in enumerate(self.possible_agents)}

    def _mask(self, robot: int) -> np.ndarray:
        return rule_mask(len(self.rules), self.driver.has_choice(robot))

    def _infos(self, tau: float) -> dict[str, dict[str, Any]]:
        driver = self.driver
        deciding = set(driver.deciding)
        picks, noops = driver.step_picks, driver.step_noops
        now, rate = driver.now, driver.gripping_rate()
        out = {}
        for r, a in enumerate(self.possible_agents):
            option = driver.option(r) if r in deciding else None
            out[a] = {
                "tau": tau,
                "time": now,
                "picks": picks[r],
                "noops": noops[r],
                "deciding": r in deciding,
                "option_time": 0.0 if option is None else option.duration,
                "candidates": driver.candidates[r],
                "action_mask": self._mask(r),
                "skipped": driver.skipped,
                "gripping_rate": rate,
                "line_seed": driver.seed,
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
