"""Semi-MDP time for any agent: a step of the environments lasts ``tau`` simulated seconds.

A decision epoch of the twin is not a fixed tick: the step's ``info["tau"]`` is the simulated
time it took (an option of variable duration). Discounting per simulated second, the return
of a trajectory is ``sum_k gamma**t_k * r_k`` with ``t_k`` the time at step k, and the
one-step target of a Q-learner is ``r + gamma**tau * max_a' Q(s', a')`` (Bradtke and Duff
1995; Sutton, Precup and Singh 1999). Two pieces make that a one-line change in an
off-the-shelf training loop:

- :func:`discount` ``(gamma, tau) -> gamma ** tau`` (numbers or arrays), and
  :func:`semi_mdp_target` for a batch;
- :class:`SemiMDPDiscount`, a Gymnasium wrapper that puts ``info["discount"] = gamma**tau``
  next to ``info["tau"]`` (and ``info["discounted_return"]``, the return so far discounted by
  simulated time), so a replay buffer can store the discount instead of a constant gamma.

``examples/dqn_semi_mdp.py`` is a CleanRL-style DQN that trains on ``pnp_twin/PickPlace-v0``
with them; the HDQN trainer (:mod:`pnp_twin.learning.train`) uses the same targets.
"""

from __future__ import annotations

from typing import Any, SupportsFloat

import gymnasium as gym
import numpy as np


def discount(gamma: float, tau: float | np.ndarray) -> float | np.ndarray:
    """``gamma ** tau``: the discount of a step that lasted ``tau`` simulated seconds."""
    if not 0.0 <= gamma <= 1.0:
        raise ValueError(f"gamma: {gamma} is not in [0, 1]")
    return np.power(gamma, tau) if isinstance(tau, np.ndarray) else float(gamma**tau)


def semi_mdp_target(
    reward: np.ndarray,
    tau: np.ndarray,
    terminated: np.ndarray,
    next_value: np.ndarray,
    gamma: float,
) -> np.ndarray:
    """``r + gamma**tau * (1 - terminated) * V(s')`` for a batch (numpy arrays)."""
    return reward + np.power(gamma, tau) * (1.0 - terminated) * next_value


class SemiMDPDiscount(gym.Wrapper[Any, Any, Any, Any]):
    """Adds ``info["discount"]`` (``gamma ** info["tau"]``) and ``info["discounted_return"]``
    (``sum gamma**t_k * r_k`` over the episode so far, ``t_k`` the simulated time at the
    start of step k) to every step of an environment whose info carries ``tau``.

    >>> env = SemiMDPDiscount(gym.make("pnp_twin/PickPlace-v0"), gamma=0.9)
    """

    def __init__(self, env: gym.Env[Any, Any], gamma: float = 0.9) -> None:
        super().__init__(env)
        discount(gamma, 0.0)  # checks gamma
        self.gamma = float(gamma)
        self._elapsed = 0.0
        self._return = 0.0

    def reset(self, **kwargs: Any) -> tuple[Any, dict[str, Any]]:
        obs, info = self.env.reset(**kwargs)
        self._elapsed, self._return = 0.0, 0.0
        return obs, {**info, "discount": 1.0, "discounted_return": 0.0}

    def step(self, action: Any) -> tuple[Any, SupportsFloat, bool, bool, dict[str, Any]]:
        obs, reward, terminated, truncated, info = self.env.step(action)
        if "tau" not in info:
            raise KeyError("SemiMDPDiscount needs info['tau'] (the step's simulated duration)")
        tau = float(info["tau"])
        self._return += self.gamma**self._elapsed * float(reward)
        self._elapsed += tau
        info = {**info, "discount": self.gamma**tau, "discounted_return": self._return}
        return obs, reward, terminated, truncated, info
