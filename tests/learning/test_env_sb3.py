"""An off-the-shelf client: Stable-Baselines3's DQN trains on ``pnp_twin/PickPlace-v0``."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest

import pnp_twin.learning.envs  # noqa: F401  (registers pnp_twin/PickPlace-v0)

sb3 = pytest.importorskip("stable_baselines3")
torch = pytest.importorskip("torch")


@pytest.fixture(scope="module")
def trained(tmp_path_factory):
    """An SB3 DQN trained briefly on two_robot, saved to a zip; its initial weights."""
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
    initial = [p.detach().clone() for p in model.q_net.parameters()]
    model.learn(total_timesteps=2_000)
    path = tmp_path_factory.mktemp("sb3") / "dqn.zip"
    model.save(path)
    return model, initial, path, kwargs


def test_sb3_dqn_trains_and_runs_an_episode(trained):
    model, initial, _path, kwargs = trained
    assert model.num_timesteps >= 2_000
    changed = [
        not torch.equal(a, b) for a, b in zip(initial, model.q_net.parameters(), strict=True)
    ]
    assert all(changed)  # every layer learned something

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


def test_sb3_model_is_a_policy_that_does_what_the_env_rollout_does(trained):
    """``sb3:MODEL.zip`` in the twin chooses what the model chooses in the env, and the
    trained model does at least as well as the worst single rule on the same seed."""
    from pnp_twin.policies.registry import make_policy
    from pnp_twin.twin.loader import load_scenario
    from pnp_twin.twin.run import simulate

    model, _initial, path, kwargs = trained
    scenario = load_scenario("two_robot", kwargs["overrides"])
    env = gym.make("pnp_twin/PickPlace-v0", scenario=scenario)
    obs, info = env.reset(options={"line_seed": 11})
    term = trunc = False
    while not (term or trunc):
        action, _ = model.predict(obs, deterministic=True)
        obs, _r, term, trunc, info = env.step(action)
    line = env.unwrapped.driver.line
    env_parts = line.recorder.parts_frame(line.belt, line.last_end)
    end = info["time"]
    result = simulate(scenario, make_policy(f"sb3:{path}"), seed=11)
    mine = result.parts
    for frame in (env_parts, mine):
        assert "decided_at" in frame
    decided = env_parts["decided_at"] < end - 1.0
    cols = ["robot", "rule", "decided_at"]
    a = env_parts.loc[decided, cols].reset_index(drop=True)
    b = mine.loc[mine["decided_at"] < end - 1.0, cols].reset_index(drop=True)
    assert len(a) > 50 and a.equals(b)
    rules = {
        r: simulate(scenario, make_policy(r), seed=11).kpis["gripping_rate"]
        for r in ("FIFO", "LIFO", "SIRO", "SD", "LD")
    }
    assert result.kpis["gripping_rate"] >= min(rules.values())


def test_run_and_evaluate_take_an_sb3_model(trained, tmp_path):
    from typer.testing import CliRunner

    from pnp_twin.cli import app

    _model, _initial, path, _kwargs = trained
    short = ["--set", "duration=10", "--set", "warmup=1"]
    run = CliRunner().invoke(app, ["run", "two_robot", "--policy", f"sb3:{path}", *short])
    assert run.exit_code == 0, run.output
    args = ["evaluate", "two_robot", "--policy", f"sb3:{path}", "--seeds", "2", "--mix", "SPT"]
    result = CliRunner().invoke(app, [*args, *short, "--out", str(tmp_path)])
    assert result.exit_code == 0, result.output
    assert "sb3 (dqn.zip)" in result.output and "FIFO" in result.output
    assert (tmp_path / "evaluation.csv").is_file()
    bad = CliRunner().invoke(app, ["run", "two_robot", "--policy", "sb3:nope.zip", *short])
    assert bad.exit_code == 2 and bad.output.startswith("error: policy: sb3: 'nope.zip'")
