"""The asynchronous multi-agent environment: PettingZoo AEC, one agent per robot."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
from gymnasium import spaces
from pettingzoo import AECEnv

from pnp_twin.learning.envs.common import (
    EpisodeLimits,
    ObservationView,
    agent_observation_space,
    check_render_mode,
    line_seed,
    render_line,
    rule_mask,
)
from pnp_twin.learning.envs.driver import EnvError, EpochDriver, is_rule_index
from pnp_twin.learning.envs.options import env_options
from pnp_twin.learning.envs.render import RENDER_FPS, RENDER_MODES
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
    :class:`~pnp_twin.learning.envs.gym_env.PickPlaceEnv` for the channels) from the cell
    holding the robot's workspace start, ``w`` cells wide, ``w`` the widest workspace in
    cells ((1, 8, 7) on paper_baseline), the same for every agent; cells beyond the belt's
    end read 0. :meth:`state` is the whole belt image ``(C, H, W)`` (``state_space``).
    With ``mask_in_observation=True`` an observation is PettingZoo's dict
    ``{"observation": window, "action_mask": mask}`` (a ``Dict`` space).

    ## Action masks
    ``infos[agent]["action_mask"]`` (and the observation's, see above): int8 over the K
    rules, all 1 when the agent's robot decides now and has a candidate part, else only
    rule 0 (its robot has no candidate, so every rule gives the same NooP, or it is not
    deciding). ``infos[agent]["candidates"]`` counts the candidates.

    ## Skipping forced NooPs
    With ``skip_noops=True`` an agent is selected only when its robot has a choice: robots
    free with no candidate take their NooP without asking (epochs where no robot has a
    choice pass without any agent acting). An agent's transition then runs from its action
    to its next selection: ``infos[agent]["tau"]`` is that time, and its rewards in between
    (its options' eq. 1 + eq. 2, the NooP penalties included) reach it through ``last()``.

    ## Rewards
    When an agent's option ends (its robot is free again), it is credited
    ``w_e * R_e + w_i * R_i``: eq. 1 ``R_e = n / t`` for n parts picked in the option's t
    seconds (0 if n = 0) and eq. 2 ``R_i = -noop_penalty`` for a NooP. ``last()`` returns
    what it was credited since it last acted. With ``team_reward=True`` every agent is
    credited the sum over all agents instead (a shared team reward).

    ## Info
    The keys of every env of this package (see ``PickPlaceEnv``), per agent: ``tau`` the
    simulated seconds since the agent last acted (0.0 before; when it is selected, the
    duration of its transition: without ``skip_noops`` its option's), ``picks`` and
    ``noops`` its grips and NooPs since it last acted, ``deciding`` whether it acts at this
    epoch, ``option_time`` the duration of its option that ended now (0.0 if none),
    ``candidates``, ``action_mask``, ``skipped`` (epochs that passed without an agent at
    the last advance), ``time``, ``gripping_rate`` (percent over the command line's window:
    parts fed after the warm-up) and ``line_seed``.

    ## Episode end
    All agents terminate when the simulated time reaches the scenario's ``duration``; all
    are truncated after ``max_episode_steps`` decision epochs answered by agents or at the
    first epoch after ``max_episode_time`` simulated seconds (None: no cap, the default).
    ``max_cycles`` (PettingZoo's name) caps each agent's own decisions instead: an agent
    that has acted ``max_cycles`` times is truncated at once (its robot keeps its last rule
    while the others play on), so that every agent acts the same number of times as in
    PettingZoo's cycle-based games. Options still running at an end earn nothing. Stepping
    after the end raises :class:`EnvError`; call ``reset()``.

    ## Seeds
    ``reset(seed=s)`` seeds the generator that draws the line's seed;
    ``reset(options={"line_seed": k})`` runs the part stream of ``pnp-twin run --seed k``.

    ## Rendering and copies
    ``render_mode`` ``"human"`` (the belt grid printed as text), ``"rgb_array"`` (the top
    view of the line) or ``"ansi"`` (the text), at ``metadata["render_fps"]``;
    ``copy.deepcopy`` and ``pickle`` replay the seed and the actions, so a copy continues
    exactly as the original. ``observation="image"`` gives 0/255 windows upscaled to sides
    of at least 36 pixels (see ``PickPlaceEnv``).

    ## Arguments
    ``scenario``, ``render_mode`` and the options of
    :class:`~pnp_twin.learning.envs.options.EnvOptions` (``termination`` defaults to
    ``t_continue`` here).

    ## Version history
    - v0: initial version (masks, ``skip_noops``, ``team_reward``, ``max_cycles`` and the
      ``human`` mode added without changing the dynamics).
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
        *,
        render_mode: str | None = None,
        **options: Any,
    ) -> None:
        super().__init__()
        self.options = opts = env_options("t_continue", {"scenario": scenario, **options})
        self.limits = EpisodeLimits.check(opts.max_episode_steps, opts.max_episode_time)
        self.max_cycles = opts.max_cycles
        self.render_mode = check_render_mode(render_mode, RENDER_MODES)
        self.driver = EpochDriver(**opts.driver_kwargs())
        self.scenario = self.driver.scenario
        self.rules = self.driver.rules
        self.reward_weights = opts.reward_weights
        self.noop_penalty = opts.noop_penalty
        self.max_episode_steps = opts.max_episode_steps
        self.possible_agents = [agent_name(r) for r in range(self.driver.n_robots)]
        self._index = {a: r for r, a in enumerate(self.possible_agents)}
        camera = self.driver.camera
        self.view = ObservationView(opts.observation, camera.window_shape)
        k = len(self.rules)
        self._observation_space = agent_observation_space(self.view, k, opts.mask_in_observation)
        self._action_space: spaces.Discrete = spaces.Discrete(k)
        self.state_space = spaces.Box(0, 1, camera.shape, dtype=np.uint8)
        self.agents: list[str] = []
        self._queue: list[int] = []
        self._actions: dict[int, int] = {}
        self._seed_rng = np.random.default_rng()
        n = self.driver.n_robots
        self._acted = [0] * n  # decisions per agent this episode
        self._acted_at = [0.0] * n  # when each agent last acted
        self._picks = [0] * n  # since each agent last acted
        self._noops = [0] * n
        self._gone: set[int] = set()  # robots whose agents are truncated (max_cycles)
        self._epochs = 0

    def observation_space(self, agent: str) -> spaces.Space[Any]:
        return self._observation_space

    def action_space(self, agent: str) -> spaces.Space[Any]:
        return self._action_space

    @property
    def _until(self) -> float:
        return math.inf if self.limits.time is None else self.limits.time

    def reset(self, seed: int | None = None, options: dict[str, Any] | None = None) -> None:
        if seed is not None:
            self._seed_rng = np.random.default_rng(seed)
        driver = self.driver
        driver.reset(line_seed(self._seed_rng, options))
        driver.skip_to_choice(self.options.skip_noops, until=self._until)
        n = driver.n_robots
        self._acted[:] = [0] * n
        self._acted_at[:] = [0.0] * n
        self._picks[:] = [0] * n
        self._noops[:] = [0] * n
        self._gone = set()
        self._epochs = 0
        self.agents = list(self.possible_agents)
        self.rewards = dict.fromkeys(self.agents, 0.0)
        self._cumulative_rewards = dict.fromkeys(self.agents, 0.0)
        self.terminations = dict.fromkeys(self.agents, False)
        self.truncations = dict.fromkeys(self.agents, False)
        self.infos: dict[str, dict[str, Any]] = {a: {} for a in self.agents}
        self._actions = {}
        self._skip_agent_selection = None
        self._epoch_ended()

    def observe(self, agent: str) -> Any:
        robot = self._index[agent]
        obs = self.view(self.driver.observe(robot))
        if self.options.mask_in_observation:
            return {"observation": obs, "action_mask": self._mask(robot)}
        return obs

    def _mask(self, robot: int) -> np.ndarray:
        return rule_mask(len(self.rules), robot in self._queue and self.driver.has_choice(robot))

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
        self._acted[robot] += 1
        self._acted_at[robot] = self.driver.now
        self._picks[robot] = self._noops[robot] = 0
        self.infos[agent]["deciding"] = False
        if self.max_cycles is not None and self._acted[robot] >= self.max_cycles:
            self._gone.add(robot)
            self.truncations[agent] = True
        if not self._queue:
            self._advance()
        else:
            self._select()
        self._accumulate_rewards()

    def _advance(self) -> None:
        """All agents of the epoch have acted: run the twin to the next epoch where one
        must act (every epoch without ``skip_noops``)."""
        driver = self.driver
        if all(self._index[a] in self._gone for a in self.agents):  # all truncated already
            self._queue = []
            self._select()
            return
        driver.act(self._actions, self.options.skip_noops, sorted(self._gone), self._until)
        self._actions = {}
        self._epochs += 1
        live = [self._index[a] for a in self.agents if self._index[a] not in self._gone]
        got = driver.step_rewards
        if self.options.team_reward:
            total = float(sum(got))
            for r in live:
                self.rewards[self.possible_agents[r]] = total
        else:
            for r in live:
                self.rewards[self.possible_agents[r]] = got[r]
        for r in range(driver.n_robots):
            self._picks[r] += driver.step_picks[r]
            self._noops[r] += driver.step_noops[r]
        self._epoch_ended()

    def _epoch_ended(self) -> None:
        """The queue, infos, ends and agent selection at the driver's new epoch."""
        driver = self.driver
        skip = self.options.skip_noops
        self._queue = [
            r for r in driver.deciding if r not in self._gone and (not skip or driver.has_choice(r))
        ]
        now, rate, seed = driver.now, driver.gripping_rate(), driver.seed
        for a in self.agents:
            r = self._index[a]
            option = driver.option(r) if r in driver.deciding else None
            self.infos[a] = {
                "tau": now - self._acted_at[r],
                "time": now,
                "picks": self._picks[r],
                "noops": self._noops[r],
                "deciding": r in self._queue,
                "option_time": 0.0 if option is None else option.duration,
                "candidates": driver.candidates[r],
                "action_mask": self._mask(r),
                "skipped": driver.skipped,
                "gripping_rate": rate,
                "line_seed": seed,
            }
        terminated = driver.done
        truncated = not terminated and self.limits.reached(self._epochs, now)
        if terminated or truncated or not self._queue:  # no queue: every agent is gone
            for a in self.agents:
                if terminated:
                    self.terminations[a] = True
                else:
                    self.truncations[a] = True
        self._select()

    def _select(self) -> None:
        """The next agent: the first of the epoch's queue, after the dead ones."""
        if self._queue:
            self.agent_selection = self.possible_agents[self._queue[0]]
        elif self.agents:
            self.agent_selection = self.agents[0]
        self._deads_step_first()

    def render(self) -> np.ndarray | str | None:  # type: ignore[override]
        """The frame of ``render_mode``: ``rgb_array`` the top view of the line, ``ansi`` the
        belt grid as text, ``human`` that text printed (:mod:`pnp_twin.learning.envs.render`);
        None without a mode or in ``human``."""
        return render_line(self.driver, self.render_mode)

    def close(self) -> None:
        """Nothing to release."""
