"""An off-the-shelf client: Stable-Baselines3's DQN trains on ``pnp_twin/PickPlace-v0``."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest

import pnp_twin.learning.envs  # noqa: F401  (registers pnp_twin/PickPlace-v0)

sb3 = pytest.importorskip("stable_baselines3")
torch = pytest.importorskip("torch")


def test_sb3_dqn_trains_and_runs_an_episode():
    torch.set_num_threads(1)
    kwargs = {
        "scenario": "two_robot",
        "overrides": {"duration": 60.0, "warmup": 5.0},
        "max_episode_steps": 400,
    }
    env = gym.make("pnp_twin/PickPlace-v0", **kwargs)
    assert env.action_space.n == 25
    model = sb3.DQN(
        "MlpPolicy",
        env,
        learning_starts=200,
        buffer_size=5_000,
        batch_size=32,
        train_freq=4,
        target_update_interval=250,
        exploration_fraction=0.5,
        gamma=0.9,
        policy_kwargs={"net_arch": [64]},
        seed=0,
        device="cpu",
    )
    model.learn(total_timesteps=2_000)
    assert model.num_timesteps >= 2_000

    eval_env = gym.make("pnp_twin/PickPlace-v0", **kwargs)
    obs, info = eval_env.reset(seed=123)
    rewards, term, trunc, steps = [], False, False, 0
    while not (term or trunc):
        action, _ = model.predict(obs, deterministic=True)
        obs, reward, term, trunc, info = eval_env.step(action)
        rewards.append(float(reward))
        steps += 1
    assert steps == 400 or term
    assert all(math.isfinite(r) for r in rewards)
    assert np.sum(rewards) > 0.0  # eq. 1 rewards for the picks outweigh the NooP penalties
    # two robots at 4 parts/s can take most of the parts (single rules reach 87-90 % here)
    assert 50.0 < info["gripping_rate"] <= 100.0
