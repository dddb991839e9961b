"""The single-agent Gymnasium environment ``pnp_twin/PickPlace-v0``."""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any, SupportsFloat

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from pnp_twin.learning.envs.common import (
    EpisodeLimits,
    ObservationView,
    check_render_mode,
    joint_mask,
    line_seed,
    render_line,
    rule_mask,
)
from pnp_twin.learning.envs.driver import EnvError, EpochDriver
from pnp_twin.learning.envs.options import env_options
from pnp_twin.learning.envs.render import RENDER_FPS, RENDER_MODES
from pnp_twin.twin.scenario import Scenario

ACTION_TYPES = ("discrete", "multidiscrete")


class PickPlaceEnv(gym.Env[np.ndarray, Any]):
    """One agent choosing the dispatching rule of every robot of a pick-and-place line.

    The twin runs until a decision epoch: one or more robots are free (under the
    termination scheme ``t_continue`` each robot decides the moment it is free; under
    ``t_all`` all decide together; under ``t_any`` the first free robot interrupts the
    others' approaches). The agent then picks a rule for each robot; the robots free now
    use theirs to choose a part (a rule's choice among the candidates, or a NooP when there
    are none) and the twin runs to the next epoch. This is the paper's "single" set-up.

    ## Action space
    With ``action_type="discrete"`` (default): ``Discrete(K**N)`` for K rules and N robots,
    the paper's joint output layer. Action ``a`` gives robot i (1-based) the rule with index
    ``(a // K**(N-i)) % K``: robot 1 is the most significant digit. With
    ``"multidiscrete"``: ``MultiDiscrete([K] * N)``, one rule index per robot. Rule index k
    means ``rules[k]``, by default the paper's ``FIFO LIFO SIRO SD LD`` (0..4). A robot that
    is not free at the epoch ignores its component (``info["deciding"]`` lists the robots
    that will use theirs at the next step).

    ## Action masks
    ``info["action_mask"]`` (int8, 1 = allowed) marks the actions that matter: a robot that
    is deciding and has a candidate part may take any rule; for every other robot (not
    deciding, or deciding with no candidate, so that any rule gives the same NooP) only
    rule 0 is allowed. With ``"discrete"`` the mask has ``K**N`` entries (the joint
    actions whose digits are all allowed; ``action_space.sample(mask)`` takes it); with
    ``"multidiscrete"`` it is ``(N, K)``, one row per robot (``action_space.sample(
    tuple(mask))``). :meth:`action_masks` returns it flat as bool, as sb3-contrib's
    ``MaskablePPO`` asks. ``info["candidates"]`` counts each robot's candidate parts.
    Every masked-out action is still accepted and behaves as the allowed one (no error).

    ## Skipping forced NooPs
    With ``skip_noops=True`` the env answers by itself every epoch at which no deciding
    robot has a candidate (on paper_baseline about half of all epochs) and returns at the
    next epoch where some robot has a choice (or at the episode's end): ``info["tau"]`` is
    all the simulated time that passed, ``info["skipped"]`` the epochs answered, and the
    step's reward sums every option that ended in between (the NooP penalties of the
    skipped epochs included). :meth:`reset` skips to the first such epoch too (the
    NooP penalties of the epochs it skips are not returned: a reset has no reward).

    ## Observation space
    ``Box(0, 1, (C, H, W), uint8)``: the belt as an occupancy image, W = 64 cells along the
    belt (column 0 at the feeder) and H = 8 across (row 0 at the lower edge) by default
    (the scenario's ``belt.grid``). With ``observation="image"`` the same grid as a picture
    for convolutional policies: ``Box(0, 255, (C, s*H, s*W), uint8)``, each cell an
    ``s x s`` block of 0 or 255, ``s`` the smallest scale giving sides of at least 36 pixels
    ((1, 40, 320) on paper_baseline; Stable-Baselines3's ``CnnPolicy`` takes it as it is).
    Channels (``channels`` keeps the first C):

    | C | name    | 1 in a cell when                                                  |
    |---|---------|-------------------------------------------------------------------|
    | 0 | parts   | a part is on the belt there (the paper's image)                   |
    | 1 | claimed | a part there is claimed by a robot about to grip it               |
    | 2 | busy    | the column lies in the workspace of a robot that is not free now  |

    ## Rewards
    For each robot whose option ended at the new epoch (the option is the time from its
    last decision to now), ``w_e * R_e + w_i * R_i`` with ``(w_e, w_i) = reward_weights``:
    the paper's eq. 1 ``R_e = n / t`` (n parts picked in the option's t seconds; 0 when
    n = 0) and eq. 2 ``R_i = -noop_penalty`` when the option was a NooP. The step reward is
    their sum. Options still running when the episode ends earn nothing.

    ## Starting state
    The belt is empty at t = 0 and every robot is at its base and free: the first epoch
    has all robots deciding. The part stream is drawn from the seed.

    ## Episode end
    Both ends, whichever comes first:

    - **terminated** at the first epoch at or after the scenario's ``duration`` (simulated
      seconds; feeding stops there; 600 s on paper_baseline);
    - **truncated** after ``max_episode_steps`` decision epochs (steps) or, with
      ``max_episode_time``, at the first epoch at or after that many simulated seconds (a
      time-based limit, so that episodes under different policies cover the same horizon).

    ``gymnasium.make("pnp_twin/PickPlace-v0")`` registers the paper's cap of 5000 steps in
    its spec (``env.spec.max_episode_steps``; Gymnasium's TimeLimit applies it; change it
    with ``gymnasium.make(..., max_episode_steps=M)``). A directly built ``PickPlaceEnv``
    has no step cap unless given one. With the paper's 5000 steps a
    600 s paper_baseline episode usually ends by the cap (near 520-560 simulated s,
    depending on the policy): give ``max_episode_steps=None`` and ``max_episode_time`` (or a
    shorter ``duration`` override) for equal horizons. Calling :meth:`step` after the end
    raises :class:`EnvError`; call :meth:`reset`.

    ## Rendering
    ``render_mode="rgb_array"``: :meth:`render` returns the top view of the line as an
    ``(H, W, 3)`` uint8 frame (belt, workspaces, parts, claimed parts in their robot's
    colour, tools, bins; :mod:`pnp_twin.learning.envs.render`); ``"ansi"``: a text view of
    the belt grid; ``"human"``: that text printed to standard output (returns None).
    ``metadata["render_fps"]`` is the frame rate a video of the steps plays
    at (one frame per decision epoch), so ``gymnasium.wrappers.RecordVideo`` works.

    ## Copies
    ``copy.deepcopy(env)`` and ``pickle`` work at any time: the copy rebuilds the line from
    the seed and replays the actions since :meth:`reset`, so it continues exactly as the
    original (for planning and search from a state).

    ## Info
    The same keys in every env of this package (here per robot, 0-based; the PettingZoo
    envs give each agent its own entry):
    ``tau``: simulated seconds the step took (discount by ``gamma**tau``); ``time``: the
    simulated time now; ``picks``: parts gripped per robot during the step; ``noops``: NooPs
    per robot during the step; ``deciding``: the 0-based robots free at the new epoch;
    ``option_time``: per robot, the duration of its option that ended at the new epoch
    (0.0 if none did); ``candidates``: per robot, its candidate parts now (0 when not
    deciding); ``action_mask``: see above; ``skipped``: epochs the step answered by itself
    (``skip_noops``); ``gripping_rate``: the command line's measure so far, percent picked
    of the parts fed at or after the scenario's warm-up that have passed the last workspace
    (0.0 until one has); ``line_seed``: the line's seed.

    ## Arguments
    ``scenario`` (a Scenario, a scenario file path or a shipped name), ``action_type``
    (``"discrete"`` or ``"multidiscrete"``), ``render_mode`` (None, ``"human"`` (prints the
    text view), ``"rgb_array"`` or ``"ansi"``), and the options of
    :class:`~pnp_twin.learning.envs.options.EnvOptions`, with their defaults there:
    ``overrides``, ``termination`` (the scenario's when None), ``rules`` (any of FIFO LIFO
    SIRO SD LD SPT; the paper's five), ``reward_weights`` (1.0, 1.0), ``noop_penalty``
    0.01, ``channels`` 1, ``max_episode_steps`` (decision steps per episode; None: no step
    cap; the registered spec adds 5000), ``max_episode_time`` (simulated seconds per
    episode, truncation; None), ``observation`` (``"grid"`` or ``"image"``),
    ``skip_noops`` (False). ``team_reward`` and ``mask_in_observation`` are accepted and
    change nothing here (the reward is the team's already; the mask is in ``info``).

    ## Seeds
    ``reset(seed=s)`` seeds ``self.np_random``, which draws the line's seed, so the same
    ``s`` gives the same part stream and, with the same actions, the same rollout. The line's
    seed is ``info["line_seed"]``; ``reset(options={"line_seed": k})`` uses ``k`` itself,
    which is the seed of ``pnp-twin run --seed k`` and of seed ``k`` in ``pnp-twin evaluate``
    (the same part stream), so an agent trained here is scored on the CLI's seeds.

    ## Version history
    - v0: initial version (rendering, copies, the registered step cap and the image
      observation added without changing the dynamics).
    """

    metadata = {"render_modes": RENDER_MODES, "render_fps": RENDER_FPS}

    def __init__(
        self,
        scenario: str | Path | Scenario = "paper_baseline",
        *,
        action_type: str = "discrete",
        render_mode: str | None = None,
        **options: Any,
    ) -> None:
        if action_type not in ACTION_TYPES:
            raise EnvError(
                f"action_type: {action_type!r} is not allowed; use one of {', '.join(ACTION_TYPES)}"
            )
        self.options = opts = env_options(None, {"scenario": scenario, **options})
        self.limits = EpisodeLimits.check(opts.step_cap, opts.max_episode_time)
        self.render_mode = check_render_mode(render_mode, RENDER_MODES)
        self.driver = EpochDriver(**opts.driver_kwargs())
        self.scenario = self.driver.scenario
        self.rules = self.driver.rules
        self.n_robots = n = self.driver.n_robots
        k = len(self.rules)
        self.action_type = action_type
        self.reward_weights = opts.reward_weights
        self.noop_penalty = opts.noop_penalty
        self.skip_noops = opts.skip_noops
        self.max_episode_steps = opts.step_cap
        self.view = ObservationView(opts.observation, self.driver.camera.shape)
        self.action_space: spaces.Space[Any]
        if action_type == "discrete":
            self.action_space = spaces.Discrete(k**n)
        else:
            self.action_space = spaces.MultiDiscrete([k] * n)
        self.observation_space = self.view.space
        self._powers = [k ** (n - 1 - i) for i in range(n)]
        self._k = k
        # joint actions decoded once (625 on paper_baseline), not digit by digit every step
        self._table: list[list[int]] | None = None
        if action_type == "discrete" and k**n <= 1 << 16:
            self._table = [self._digits(a) for a in range(k**n)]
        self._steps = 0
        self._over = True  # no episode yet

    def decode(self, action: Any) -> list[int]:
        """The rule index per robot (0-based robots) of an action (do not modify the list)."""
        if self.action_type == "discrete":
            a = int(action)
            if not 0 <= a < self._k**self.n_robots:
                raise EnvError(f"action: {a} is not in 0..{self._k**self.n_robots - 1}")
            return self._table[a] if self._table is not None else self._digits(a)
        out = [int(x) for x in np.asarray(action).reshape(-1)]
        if len(out) != self.n_robots or not all(0 <= x < self._k for x in out):
            raise EnvError(
                f"action: {out} is not one rule index in 0..{self._k - 1} per robot "
                f"({self.n_robots} robots)"
            )
        return out

    def _digits(self, a: int) -> list[int]:
        k = self._k
        return [(a // p) % k for p in self._powers]

    def encode(self, rule_indices: Sequence[int]) -> int:
        """The Discrete action giving robot i the rule index ``rule_indices[i]``."""
        return sum(int(r) * p for r, p in zip(rule_indices, self._powers, strict=True))

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        super().reset(seed=seed)
        driver = self.driver
        driver.reset(line_seed(self.np_random, options))
        driver.skip_to_choice(self.skip_noops, until=self._until)
        self._steps = 0
        self._over = False
        return self._get_obs(), self._get_info(driver.now)

    def step(self, action: Any) -> tuple[np.ndarray, SupportsFloat, bool, bool, dict[str, Any]]:
        if self._over:
            raise EnvError("step: the episode is over (or not started); call reset()")
        driver = self.driver
        before = driver.now
        choice = self.decode(action)
        driver.act({r: choice[r] for r in driver.deciding}, self.skip_noops, until=self._until)
        self._steps += 1
        reward = float(sum(driver.step_rewards))
        terminated = driver.done
        truncated = not terminated and self.limits.reached(self._steps, driver.now)
        self._over = terminated or truncated
        return self._get_obs(), reward, terminated, truncated, self._get_info(driver.now - before)

    @property
    def _until(self) -> float:
        return math.inf if self.limits.time is None else self.limits.time

    def action_masks(self) -> np.ndarray:
        """The action mask now, flat and bool (sb3-contrib's ``MaskablePPO`` convention;
        for ``"multidiscrete"`` the robots' rows one after the other)."""
        return self._mask().reshape(-1).astype(bool)

    def _mask(self) -> np.ndarray:
        driver, k = self.driver, self._k
        rows = [rule_mask(k, driver.has_choice(r)) for r in range(self.n_robots)]
        if self.action_type == "discrete":
            return joint_mask(rows)
        return np.stack(rows)

    def render(self) -> np.ndarray | str | None:  # type: ignore[override]
        """The frame of ``render_mode`` (see the class docstring); None without one."""
        return render_line(self.driver, self.render_mode)

    def _get_obs(self) -> np.ndarray:
        return self.view(self.driver.observe(None))

    def _get_info(self, tau: float) -> dict[str, Any]:
        driver = self.driver
        options = [0.0] * self.n_robots
        for r in driver.deciding:
            o = driver.option(r)
            if o is not None:
                options[r] = o.duration
        return {
            "tau": tau,
            "time": driver.now,
            "picks": driver.step_picks,
            "noops": list(driver.step_noops),
            "deciding": list(driver.deciding),
            "option_time": options,
            "candidates": list(driver.candidates),
            "action_mask": self._mask(),
            "skipped": driver.skipped,
            "gripping_rate": driver.gripping_rate(),
            "line_seed": driver.seed,
        }
