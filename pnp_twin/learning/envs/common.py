"""What the three environments share: episode limits, the observation option, seeds and
rendering (each a few lines, so the env classes stay thin layers over the driver)."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from gymnasium import spaces

from pnp_twin.learning.envs import render
from pnp_twin.learning.envs.driver import EnvError, EpochDriver

OBSERVATIONS = ("grid", "image")
IMAGE_MIN_SIDE = 36
"""The smallest image side Stable-Baselines3's ``CnnPolicy`` (NatureCNN) accepts."""


@dataclass(frozen=True)
class EpisodeLimits:
    """Truncation: a cap on decision steps and/or on simulated seconds (None: no cap)."""

    steps: int | None = None
    time: float | None = None

    @classmethod
    def check(cls, steps: int | None, time: float | None) -> EpisodeLimits:
        if steps is not None and (isinstance(steps, bool) or int(steps) != steps or steps < 1):
            raise EnvError(f"max_episode_steps: {steps!r} is not allowed; give an integer >= 1")
        if time is not None and not (math.isfinite(time) and time > 0):
            raise EnvError(f"max_episode_time: {time!r} is not allowed; give seconds > 0")
        return cls(None if steps is None else int(steps), None if time is None else float(time))

    def reached(self, steps: int, now: float) -> bool:
        """True once either cap is reached."""
        return (self.steps is not None and steps >= self.steps) or (
            self.time is not None and now >= self.time
        )


def image_scale(shape: Sequence[int]) -> int:
    """Pixels per grid cell of the ``image`` observation: each side at least 36 pixels."""
    return max(1, math.ceil(IMAGE_MIN_SIDE / min(shape[1], shape[2])))


class ObservationView:
    """The ``observation`` option: the 0/1 grid as it is, or a 0/255 upscaled image."""

    def __init__(self, observation: str, shape: Sequence[int]) -> None:
        if observation not in OBSERVATIONS:
            raise EnvError(
                f"observation: {observation!r} is not allowed; use one of {', '.join(OBSERVATIONS)}"
            )
        self.image = observation == "image"
        c, h, w = shape
        if self.image:
            self.scale = image_scale(shape)
            self.space = spaces.Box(0, 255, (c, h * self.scale, w * self.scale), dtype=np.uint8)
        else:
            self.scale = 1
            self.space = spaces.Box(0, 1, (c, h, w), dtype=np.uint8)

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        if not self.image:
            return obs
        s = self.scale
        return obs.repeat(s, axis=1).repeat(s, axis=2) * np.uint8(255)


def agent_observation_space(view: ObservationView, k: int, with_mask: bool) -> spaces.Space[Any]:
    """One agent's observation space: its window, or with ``with_mask`` PettingZoo's
    ``{"observation", "action_mask"}`` dict (the mask over the ``k`` rules)."""
    if not with_mask:
        return view.space
    mask = spaces.Box(0, 1, (k,), dtype=np.int8)
    return spaces.Dict({"observation": view.space, "action_mask": mask})


def check_render_mode(mode: str | None, allowed: Sequence[str]) -> str | None:
    if mode is not None and mode not in allowed:
        raise EnvError(f"render_mode: {mode!r} is not allowed; use None or {', '.join(allowed)}")
    return mode


def render_line(driver: EpochDriver, mode: str | None) -> np.ndarray | str | None:
    """The frame of ``mode`` for the driver's line now (None without a mode)."""
    if mode is None:
        return None
    if driver.line is None:
        raise EnvError("render: call reset() before render()")
    if mode == "rgb_array":
        line = driver.line
        cached = getattr(driver, "_render_base", None)
        if cached is None or cached[0] is not line:  # a new episode: a new line
            cached = (line, render.background(line))
            driver._render_base = cached  # type: ignore[attr-defined]
        return render.frame(line, cached[1])
    text = render.text(driver.line, driver.gripping_rate())
    if mode == "human":
        print(text, flush=True)
        return None
    return text


def rule_mask(k: int, choice: bool) -> np.ndarray:
    """An agent's action mask over its K rules (int8, 1 = allowed): every rule when its
    robot has a choice, else rule 0 alone (every rule gives the same NooP, or the robot is
    not deciding and its action is ignored)."""
    mask = np.zeros(k, dtype=np.int8)
    if choice:
        mask[:] = 1
    else:
        mask[0] = 1
    return mask


def joint_mask(masks: Sequence[np.ndarray]) -> np.ndarray:
    """The mask of the joint Discrete(K**N) action from per-robot masks (robot 1 the most
    significant digit): a joint action is allowed when each robot's digit is."""
    out = np.ones(1, dtype=np.int8)
    for m in masks:
        out = (out[:, None] * m[None, :]).reshape(-1)
    return out


def team(rewards: Mapping[str, float]) -> dict[str, float]:
    """Every agent's reward replaced by the sum of all (the ``team_reward`` option)."""
    total = float(sum(rewards.values()))
    return dict.fromkeys(rewards, total)


def line_seed(rng: np.random.Generator, options: Mapping[str, Any] | None) -> int:
    """The line's seed for a reset: ``options["line_seed"]`` (the CLI's ``--seed``) if
    given, else drawn from the env's seeded generator."""
    if options and options.get("line_seed") is not None:
        seed = options["line_seed"]
        if isinstance(seed, bool) or not isinstance(seed, int | np.integer) or seed < 0:
            raise EnvError(f"options: line_seed {seed!r} is not allowed; give an integer >= 0")
        return int(seed)
    return int(rng.integers(2**31 - 1))
