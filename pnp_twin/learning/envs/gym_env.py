"""The single-agent Gymnasium environment ``pnp_twin/PickPlace-v0``."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any, SupportsFloat

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from pnp_twin.learning.envs.driver import EnvError, EpochDriver
from policies.rules import PAPER_RULES
from twin.scenario import Scenario

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

    ## Observation space
    ``Box(0, 1, (C, H, W), uint8)``: the belt as an occupancy image, W = 64 cells along the
    belt (column 0 at the feeder) and H = 8 across (row 0 at the lower edge) by default
    (the scenario's ``belt.grid``). Channels (``channels`` keeps the first C):

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
    Terminated when the simulated time reaches the scenario's ``duration`` (feeding stops).
    Truncated after ``max_episode_steps`` steps (decision epochs). ``gymnasium.make(...,
    max_episode_steps=M)`` adds Gymnasium's own TimeLimit on top, which truncates too.

    ## Info
    ``tau``: simulated seconds the step took (discount by ``gamma**tau``); ``time``: the
    simulated time now; ``picks``: parts gripped per robot during the step; ``deciding``:
    0-based robots free at the new epoch; ``options``: per robot, the duration of the
    option that ended (``nan`` if none); ``gripping_rate``: percent of the parts that have
    passed the last workspace since the start that were picked.

    ## Arguments
    - ``scenario``: a Scenario, a scenario file path or a shipped name ("paper_baseline").
    - ``overrides``: dotted-path scenario overrides, e.g. ``{"feeder.rate": 12}``.
    - ``termination``: ``t_continue`` | ``t_all`` | ``t_any``; the scenario's when None.
    - ``action_type``: ``"discrete"`` or ``"multidiscrete"``.
    - ``rules``: rule names (any of FIFO LIFO SIRO SD LD SPT), default the paper's five.
    - ``reward_weights``: (extrinsic, intrinsic) weights, default (1.0, 1.0).
    - ``noop_penalty``: the NooP penalty of eq. 2, default 0.01.
    - ``channels``: observation channels, 1 to 3 (default 1).
    - ``max_episode_steps``: decision steps per episode, default 5000 (the paper's).

    ``reset(seed=s)`` seeds the line from ``self.np_random``, so the same seed gives the
    same part stream and, with the same actions, the same rollout.

    ## Version history
    - v0: initial version.
    """

    metadata = {"render_modes": []}

    def __init__(
        self,
        scenario: str | Path | Scenario = "paper_baseline",
        overrides: Mapping[str, Any] | None = None,
        termination: str | None = None,
        action_type: str = "discrete",
        rules: Sequence[str] = PAPER_RULES,
        reward_weights: tuple[float, float] = (1.0, 1.0),
        noop_penalty: float = 0.01,
        channels: int = 1,
        max_episode_steps: int = 5000,
    ) -> None:
        if action_type not in ACTION_TYPES:
            raise EnvError(
                f"action_type: {action_type!r} is not allowed; use one of {', '.join(ACTION_TYPES)}"
            )
        if max_episode_steps < 1:
            raise EnvError(f"max_episode_steps: {max_episode_steps} must be >= 1")
        if len(reward_weights) != 2:
            raise EnvError("reward_weights: give two numbers (extrinsic, intrinsic)")
        self.driver = EpochDriver(
            scenario, termination=termination, rules=rules, channels=channels, overrides=overrides
        )
        self.scenario = self.driver.scenario
        self.rules = self.driver.rules
        self.n_robots = n = self.driver.n_robots
        k = len(self.rules)
        self.action_type = action_type
        self.reward_weights = (float(reward_weights[0]), float(reward_weights[1]))
        self.noop_penalty = float(noop_penalty)
        self.max_episode_steps = int(max_episode_steps)
        self.action_space: spaces.Space[Any]
        if action_type == "discrete":
            self.action_space = spaces.Discrete(k**n)
        else:
            self.action_space = spaces.MultiDiscrete([k] * n)
        self.observation_space = spaces.Box(0, 1, self.driver.camera.shape, dtype=np.uint8)
        self._powers = [k ** (n - 1 - i) for i in range(n)]
        self._k = k
        # joint actions decoded once (625 on paper_baseline), not digit by digit every step
        self._table: list[list[int]] | None = None
        if action_type == "discrete" and k**n <= 1 << 16:
            self._table = [self._digits(a) for a in range(k**n)]
        self._steps = 0

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
        self.driver.reset(int(self.np_random.integers(2**31 - 1)))
        self._steps = 0
        return self._get_obs(), self._get_info(0.0)

    def step(self, action: Any) -> tuple[np.ndarray, SupportsFloat, bool, bool, dict[str, Any]]:
        driver = self.driver
        before = driver.now
        choice = self.decode(action)
        deciding = driver.act({r: choice[r] for r in driver.deciding})
        self._steps += 1
        weights, penalty = self.reward_weights, self.noop_penalty
        reward = 0.0
        for r in deciding:
            reward += driver.reward(r, weights, penalty)
        terminated = driver.done
        truncated = not terminated and self._steps >= self.max_episode_steps
        return self._get_obs(), reward, terminated, truncated, self._get_info(driver.now - before)

    def _get_obs(self) -> np.ndarray:
        return self.driver.observe(None)

    def _get_info(self, tau: float) -> dict[str, Any]:
        driver = self.driver
        options = [float("nan")] * self.n_robots
        for r in driver.deciding:
            o = driver.option(r)
            if o is not None:
                options[r] = o.duration
        return {
            "tau": tau,
            "time": driver.now,
            "picks": driver.step_picks,
            "deciding": list(driver.deciding),
            "options": options,
            "gripping_rate": driver.gripping_rate(),
        }
