"""RLlib's PPO runs a few iterations on the PettingZoo env through RLlib's own wrapper.

RLlib needs ``pip install 'ray[rllib]'`` (which pins gymnasium 1.2.2; the project supports
1.2.2 and the newest 1.x). Without it this test is skipped, with the reason (a failure in CI,
where the test extra installs it: tests/conftest.py).
"""

from __future__ import annotations

import signal

import numpy as np
import pytest

try:
    from ray.rllib.algorithms.ppo import PPOConfig
    from ray.rllib.env.wrappers.pettingzoo_env import ParallelPettingZooEnv
except ImportError as e:  # ray without the rllib extra (dm_tree, lz4, ...) or no ray at all
    pytest.skip(f"RLlib is not installed ({e}); pip install 'ray[rllib]'", allow_module_level=True)


def _make(_config):
    import supersuit as ss

    from pnp_twin.learning.envs import pickplace_v0

    par = pickplace_v0.parallel_env(
        overrides={"duration": 20.0, "warmup": 1.0}, max_episode_steps=50
    )
    # RLlib's default MLP takes flat float32 observations
    return ParallelPettingZooEnv(ss.dtype_v0(ss.flatten_v0(par), np.float32))


def test_rllib_ppo_trains_a_few_iterations_on_the_pettingzoo_env():
    import ray
    from ray.tune.registry import register_env

    register_env("pnp_twin_parallel", _make)
    # ray.init installs its own SIGTERM handler in this (pytest's) process: put pytest's back
    handlers = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)}
    ray.init(num_cpus=1, include_dashboard=False, log_to_driver=False)
    try:
        config = (
            PPOConfig()
            .environment("pnp_twin_parallel")
            .multi_agent(policies={"shared"}, policy_mapping_fn=lambda aid, *a, **k: "shared")
            .env_runners(num_env_runners=0)
            .training(train_batch_size_per_learner=200, minibatch_size=100, num_epochs=1)
            .rl_module(model_config={"fcnet_hiddens": [32]})
            .debugging(seed=0)
        )
        algo = config.build_algo()
        results = [algo.train() for _ in range(2)]
        algo.stop()
    finally:
        ray.shutdown()
        for s, handler in handlers.items():
            signal.signal(s, handler)
    sampled = [r["env_runners"]["num_env_steps_sampled_lifetime"] for r in results]
    assert sampled[0] >= 200 and sampled[1] > sampled[0]
    assert np.isfinite(results[-1]["env_runners"]["episode_return_mean"])
