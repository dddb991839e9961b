"""The asynchronous multi-agent environment: PettingZoo AEC, one agent per robot."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from gymnasium import spaces
from pettingzoo import AECEnv

from pnp_twin.learning.envs.common import (
    EpisodeLimits,
    ObservationView,
    check_render_mode,
    line_seed,
    render_line,
)
from pnp_twin.learning.envs.driver import EnvError, EpochDriver, is_rule_index
from pnp_twin.learning.envs.render import RENDER_FPS, RENDER_MODES
from pnp_twin.policies.rules import PAPER_RULES
from pnp_twin.twin.scenario import Scenario


def agent_name(robot: int) -> str:
    """The agent of a 0-based robot index: ``robot_1`` is the most upstream robot."""
    return f"robot_{robot + 1}"


class PickPlaceAEC(AECEnv[str, np.ndarray, int]):
    """Each robot an agent that picks its own dispatching rule the moment it is free.

    The paper's asynchronous set-up (termination scheme ``t_continue`` by default): the
    twin runs until one or more robots are free; ``agent_selection`` is the free robot
    (robots free at the same instant take turns, upstream first, and the twin only moves on
    once all of them have acted). Each agent sees only its own workspace window.

    ## Agents
    ``robot_1`` .. ``robot_N``, upstream first (``robot_i`` is the driver's robot i - 1).

    ## Action space
    ``Discrete(K)``: index into ``rules`` (default the paper's ``FIFO LIFO SIRO SD LD``).
    The rule chooses a part among the robot's candidates; with none the robot takes a NooP.

    ## Observation space
    ``Box(0, 1, (C, H, w), uint8)``: the columns of the belt image (see
    :class:`~pnp_twin.learning.envs.gym_env.PickPlaceEnv` for the channels) from the cell holding
    the
    robot's workspace start, ``w`` cells wide, ``w`` the widest workspace in cells (14 on
    paper_baseline), the same for every agent; cells beyond the belt's end read 0.
    :meth:`state` is the whole belt image ``(C, H, W)`` (``state_space``).

    ## Rewards
    When an agent's option ends (it is free again), it is credited ``w_e * R_e + w_i * R_i``:
    eq. 1 ``R_e = n / t`` for n parts picked in the option's t seconds (0 if n = 0) and
    eq. 2 ``R_i = -noop_penalty`` for a NooP. ``last()`` returns it when the agent is next
    selected. ``infos[agent]``: ``tau`` the duration of its last option (0.0 before the
    first ends), ``picks`` and ``noop`` of that option, ``time`` the simulated time now, and
    ``gripping_rate`` so far (percent).

    ## Episode end
    All agents terminate when the simulated time reaches the scenario's ``duration``; all
    are truncated after ``max_episode_steps`` decision epochs or at the first epoch after
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

    ## Arguments
    ``scenario``, ``overrides``, ``termination`` (default ``t_continue``), ``rules``,
    ``reward_weights`` (extrinsic, intrinsic), ``noop_penalty``, ``channels``,
    ``max_episode_steps``: as for :class:`~pnp_twin.learning.envs.gym_env.PickPlaceEnv`.

    ## Version history
    - v0: initial version.
    """

    metadata = {
        "name": "pnp_twin_pickplace_aec_v0",
        "render_modes": RENDER_MODES,
        "render_fps": RENDER_FPS,
        "is_parallelizable": False,
    }

    def __init__(
        self,
        scenario: str | Path | Scenario = "paper_baseline",
        overrides: Mapping[str, Any] | None = None,
        termination: str | None = "t_continue",
        rules: Sequence[str] = PAPER_RULES,
        reward_weights: tuple[float, float] = (1.0, 1.0),
        noop_penalty: float = 0.01,
        channels: int = 1,
        max_episode_steps: int | None = None,
        max_episode_time: float | None = None,
        observation: str = "grid",
        render_mode: str | None = None,
    ) -> None:
        super().__init__()
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
        self._index = {a: r for r, a in enumerate(self.possible_agents)}
        camera = self.driver.camera
        self.view = ObservationView(observation, camera.window_shape)
        self._observation_space = self.view.space
        self._action_space: spaces.Discrete = spaces.Discrete(len(self.rules))
        self.state_space = spaces.Box(0, 1, camera.shape, dtype=np.uint8)
        self.agents: list[str] = []
        self._queue: list[int] = []
        self._actions: dict[int, int] = {}
        self._seed_rng = np.random.default_rng()

    def observation_space(self, agent: str) -> spaces.Space[Any]:
        return self._observation_space

    def action_space(self, agent: str) -> spaces.Space[Any]:
        return self._action_space

    def reset(self, seed: int | None = None, options: dict[str, Any] | None = None) -> None:
        if seed is not None:
            self._seed_rng = np.random.default_rng(seed)
        self.driver.reset(line_seed(self._seed_rng, options))
        self.agents = list(self.possible_agents)
        self.rewards = dict.fromkeys(self.agents, 0.0)
        self._cumulative_rewards = dict.fromkeys(self.agents, 0.0)
        self.terminations = dict.fromkeys(self.agents, False)
        self.truncations = dict.fromkeys(self.agents, False)
        self.infos = {
            a: {"tau": 0.0, "picks": 0, "noop": False, "time": 0.0, "gripping_rate": 0.0}
            for a in self.agents
        }
        self._actions = {}
        self._queue = list(self.driver.deciding)
        self.agent_selection = self.possible_agents[self._queue[0]]

    def observe(self, agent: str) -> np.ndarray:
        return self.view(self.driver.observe(self._index[agent]))

    def state(self) -> np.ndarray:
        return self.driver.observe(None)

    def step(self, action: int | None) -> None:
        if not self.agents:
            raise EnvError("step: the episode is over (or not started); call reset()")
        agent = self.agent_selection
        if self.terminations[agent] or self.truncations[agent]:
            self._was_dead_step(action)
            return
        if action is None or not is_rule_index(action, len(self.rules)):
            raise EnvError(f"action: {action!r} for {agent} is not in 0..{len(self.rules) - 1}")
        self._cumulative_rewards[agent] = 0.0
        for a in self.agents:
            self.rewards[a] = 0.0
        robot = self._queue.pop(0)
        self._actions[robot] = int(action)
        if not self._queue:
            self._advance()
        self.agent_selection = self.possible_agents[self._queue[0]]
        self._accumulate_rewards()

    def _advance(self) -> None:
        """All robots of the epoch have acted: run the twin to the next epoch."""
        driver = self.driver
        deciding = driver.act(self._actions)
        self._actions = {}
        weights, penalty = self.reward_weights, self.noop_penalty
        now, rate = driver.now, driver.gripping_rate()
        for r in deciding:
            option = driver.option(r)
            if option is not None:
                agent = self.possible_agents[r]
                self.rewards[agent] = driver.reward(r, weights, penalty)
                self.infos[agent] = {
                    "tau": option.duration,
                    "picks": option.picks,
                    "noop": option.noop,
                }
        for info in self.infos.values():
            info["time"], info["gripping_rate"] = now, rate
        self._queue = list(deciding)
        terminated = driver.done
        truncated = not terminated and self.limits.reached(driver.steps, driver.now)
        if terminated or truncated:
            for a in self.agents:
                self.terminations[a] = terminated
                self.truncations[a] = truncated

    def render(self) -> np.ndarray | str | None:  # type: ignore[override]
        """The frame of ``render_mode``: ``rgb_array`` the top view of the line, ``ansi`` the
        belt grid as text (:mod:`pnp_twin.learning.envs.render`); None without a mode."""
        return render_line(self.driver, self.render_mode)

    def close(self) -> None:
        """Nothing to release."""
