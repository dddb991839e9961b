"""The environments in RL researchers' stacks: rendering, copies, the registered cap, the
PettingZoo constructors, the image observation, seeds across tools, SuperSuit + SB3 PPO."""

from __future__ import annotations

import copy
import pickle
import warnings

import gymnasium as gym
import numpy as np
import pytest

from pnp_twin.learning.envs import ENV_ID, EnvError, PickPlaceEnv, pickplace_v0, render
from pnp_twin.learning.envs.pz_aec import PickPlaceAEC
from pnp_twin.learning.envs.pz_parallel import PickPlaceParallel
from pnp_twin.policies import make_policy
from pnp_twin.twin import picture
from pnp_twin.twin.loader import load_scenario
from pnp_twin.twin.run import simulate

SHORT = {"duration": 20.0, "warmup": 1.0}


def _pixel(line, x, y, shape):
    return picture.Canvas(render.layout(line), np.zeros(shape, np.uint8)).px(x, y)


def _gym_steps(env, actions):
    out = []
    for a in actions:
        obs, r, term, trunc, info = env.step(a)
        out.append((obs.tobytes(), r, term, trunc, info["time"], tuple(info["deciding"])))
        if term or trunc:
            break
    return out


# -- rendering ------------------------------------------------------------------------------
def test_gym_make_renders_rgb_frames_and_ansi_text():
    env = gym.make(ENV_ID, overrides=SHORT, render_mode="rgb_array")
    assert env.metadata["render_fps"] > 0 and "rgb_array" in env.metadata["render_modes"]
    env.reset(seed=0)
    for _ in range(30):
        env.step(env.action_space.sample())
    frame = env.render()
    assert frame.dtype == np.uint8 and frame.ndim == 3 and frame.shape[2] == 3
    assert frame.shape[1] >= 600 and frame.shape[0] >= 100  # readable
    line = env.unwrapped.driver.line
    # parts on the belt are white squares; claimed ones in their robot's colour
    assert (frame == 255).all(axis=2).any()
    claimed = [r for r in line.robots if r.claimed >= 0]
    for r in claimed:  # the tool's square is drawn in the robot's colour
        row, col = _pixel(line, *r.tool, frame.shape)
        assert tuple(frame[row, col]) == render.colour(r.index)
    text = PickPlaceEnv(overrides=SHORT, render_mode="ansi")
    text.reset(seed=0)
    view = text.render()
    rows = view.splitlines()
    assert rows[0].startswith("t=") and len(rows) == 1 + 8 + 1
    assert all(len(r) == 64 for r in rows[1:])
    assert set("".join(rows[1:9])) <= set(".o123456789")


def test_frames_follow_the_parts_and_differ_between_steps():
    env = PickPlaceEnv(overrides=SHORT, render_mode="rgb_array")
    env.reset(seed=1)
    for _ in range(20):  # the first part reaches the belt after 0.3 s
        env.step(0)
    frames = [env.render()]
    for _ in range(5):
        env.step(0)
        frames.append(env.render())
    assert all(f.shape == frames[0].shape for f in frames)
    assert any(not np.array_equal(a, b) for a, b in zip(frames, frames[1:], strict=False))
    assert PickPlaceEnv(overrides=SHORT).render() is None
    with pytest.raises(EnvError, match="^render_mode: 'video' is not allowed"):
        PickPlaceEnv(render_mode="video")


def test_render_collection_gathers_one_frame_per_step():
    env = gym.wrappers.RenderCollection(gym.make(ENV_ID, overrides=SHORT, render_mode="rgb_array"))
    env.reset(seed=0)
    for _ in range(4):
        env.step(0)
    frames = env.render()
    assert len(frames) == 5 and frames[0].shape[2] == 3


@pytest.mark.parametrize("mode", ["rgb_array", "ansi"])
def test_pettingzoo_envs_render_both_modes(mode):
    aec = pickplace_v0.env(overrides=SHORT, render_mode=mode)
    aec.reset(seed=0)
    par = pickplace_v0.parallel_env(overrides=SHORT, render_mode=mode)
    par.reset(seed=0)
    for out in (aec.render(), par.render()):
        assert isinstance(out, np.ndarray if mode == "rgb_array" else str)
    assert aec.render_mode == par.render_mode == mode
    assert isinstance(pickplace_v0.raw_env(), PickPlaceAEC)
    assert isinstance(pickplace_v0.parallel_env(), PickPlaceParallel)


# -- copies ---------------------------------------------------------------------------------
@pytest.mark.parametrize("how", ["deepcopy", "pickle"])
def test_gym_copy_at_step_k_continues_exactly_as_the_original(how):
    env = PickPlaceEnv(overrides=SHORT)
    env.reset(seed=5)
    rng = np.random.default_rng(0)
    _gym_steps(env, [int(rng.integers(625)) for _ in range(40)])
    clone = copy.deepcopy(env) if how == "deepcopy" else pickle.loads(pickle.dumps(env))
    actions = [int(rng.integers(625)) for _ in range(60)]
    assert _gym_steps(clone, actions) == _gym_steps(env, actions)
    # and the copies' own future resets follow the same seed stream
    assert np.array_equal(clone.reset()[0], env.reset()[0])


def test_pettingzoo_copies_continue_exactly():
    aec = PickPlaceAEC(overrides=SHORT)
    aec.reset(seed=2)
    for _ in range(25):
        aec.step(1)
    twin = copy.deepcopy(aec)
    for a in [0, 3, 4, 2, 1] * 8:
        for env in (aec, twin):
            env.step(a)
        assert aec.agent_selection == twin.agent_selection
        assert np.array_equal(aec.observe(aec.agent_selection), twin.observe(twin.agent_selection))
        assert aec.rewards == twin.rewards
    par = PickPlaceParallel(overrides=SHORT)
    par.reset(seed=3)
    par.step(dict.fromkeys(par.agents, 2))
    clone = pickle.loads(pickle.dumps(par))
    for k in range(10):
        acts = {a: (k + i) % 5 for i, a in enumerate(par.possible_agents)}
        o1, r1, *_ = par.step(acts)
        o2, r2, *_ = clone.step(acts)
        assert r1 == r2 and all(np.array_equal(o1[a], o2[a]) for a in o1)


# -- episode ends ---------------------------------------------------------------------------
def test_the_step_cap_is_registered_and_both_ends_work():
    env = gym.make(ENV_ID, overrides=SHORT)
    assert env.spec.max_episode_steps == 5000
    assert PickPlaceEnv().max_episode_steps is None
    short = gym.make(ENV_ID, overrides=SHORT, max_episode_steps=6)
    short.reset(seed=0)
    flags = [short.step(0)[2:4] for _ in range(6)]
    assert flags[-1] == (False, True) and flags[:-1] == [(False, False)] * 5
    timed = PickPlaceEnv(overrides=SHORT, max_episode_time=4.0)
    timed.reset(seed=0)
    term = trunc = False
    while not (term or trunc):
        _o, _r, term, trunc, info = timed.step(0)
    assert trunc and not term and 4.0 <= info["time"] < 5.0


def test_step_after_the_end_raises_in_every_env():
    gym_env = PickPlaceEnv(overrides=SHORT, max_episode_steps=3)
    with pytest.raises(EnvError, match="call reset"):
        gym_env.step(0)
    gym_env.reset(seed=0)
    for _ in range(3):
        gym_env.step(0)
    with pytest.raises(EnvError, match=r"^step: the episode is over"):
        gym_env.step(0)
    aec = PickPlaceAEC(overrides=SHORT, max_episode_steps=3)
    aec.reset(seed=0)
    for _agent in aec.agent_iter(1000):
        _o, _r, term, trunc, _i = aec.last()
        aec.step(None if term or trunc else 0)
    with pytest.raises(EnvError, match=r"^step: the episode is over"):
        aec.step(0)
    par = PickPlaceParallel(overrides=SHORT, max_episode_steps=2)
    par.reset(seed=0)
    par.step(dict.fromkeys(par.agents, 0))
    par.step(dict.fromkeys(par.possible_agents, 0))
    with pytest.raises(EnvError, match=r"^step: the episode is over"):
        par.step(dict.fromkeys(par.possible_agents, 0))


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [
        ({"max_episode_steps": 0}, "max_episode_steps"),
        ({"max_episode_time": -1.0}, "max_episode_time"),
        ({"observation": "rgb"}, "observation"),
    ],
)
def test_bad_episode_and_observation_options_are_one_line_errors(kwargs, field):
    for cls in (PickPlaceEnv, PickPlaceAEC, PickPlaceParallel):
        with pytest.raises(EnvError) as e:
            cls(**kwargs)
        assert str(e.value).startswith(field) and "\n" not in str(e.value)


# -- observations for CNN policies ----------------------------------------------------------
def test_image_observation_passes_sb3_check_env_without_warnings():
    from stable_baselines3.common.env_checker import check_env

    env = PickPlaceEnv(overrides=SHORT, observation="image")
    assert env.observation_space.shape == (1, 40, 320)
    assert env.observation_space.high.max() == 255
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        check_env(env)
    obs, _ = env.reset(seed=0)
    grid = PickPlaceEnv(overrides=SHORT)
    ref, _ = grid.reset(seed=0)
    assert np.array_equal(obs[:, ::5, ::5], ref * 255)
    assert set(np.unique(obs)) <= {0, 255}


def test_sb3_cnn_policy_takes_the_image_observation():
    from stable_baselines3 import PPO

    env = PickPlaceEnv(overrides=SHORT, observation="image", max_episode_steps=64)
    model = PPO("CnnPolicy", env, n_steps=32, batch_size=32, n_epochs=1, seed=0, device="cpu")
    model.learn(32)
    action, _ = model.predict(env.reset(seed=0)[0], deterministic=True)
    assert env.action_space.contains(int(action))
    # the same model as a policy of the twin (sb3:MODEL.zip) sees the same upscaled image
    from pnp_twin.policies.sb3_policy import SB3Policy

    policy = SB3Policy(model)
    env = PickPlaceEnv(overrides=SHORT, observation="image")
    obs, info = env.reset(options={"line_seed": 4})
    term = False
    while not term:  # the whole 20 s episode
        obs, _r, term, _trunc, info = env.step(model.predict(obs, deterministic=True)[0])
    line = env.driver.line
    in_env = line.recorder.parts_frame(line.belt, line.last_end)
    result = simulate(env.scenario, policy, seed=4)
    assert policy.image and policy.scale == 5
    cols = ["robot", "rule", "decided_at"]
    end = info["time"] - 0.5
    a = in_env.loc[in_env["decided_at"] < end, cols].reset_index(drop=True)
    b = result.parts.loc[result.parts["decided_at"] < end, cols].reset_index(drop=True)
    assert len(a) > 20 and a.equals(b)


# -- seeds across tools ---------------------------------------------------------------------
def test_line_seed_option_is_the_cli_seed():
    scenario = load_scenario("paper_baseline", SHORT)
    env = PickPlaceEnv(scenario)
    _obs, info = env.reset(options={"line_seed": 7})
    assert info["line_seed"] == 7
    fifo = env.rules.index("FIFO")
    term = trunc = False
    while not (term or trunc):
        _o, _r, term, trunc, info = env.step(env.encode([fifo] * env.n_robots))
    line = env.driver.line
    run_line = simulate(scenario, make_policy("FIFO"), seed=7)
    fed = run_line.parts["fed_at"].to_numpy()
    assert np.array_equal(np.asarray(line.belt.fed), fed)
    _obs, info = env.reset(seed=3)
    assert info["line_seed"] != 3  # the env seed draws the line seed
    for pz in (PickPlaceAEC(scenario), PickPlaceParallel(scenario)):
        pz.reset(options={"line_seed": 7})
        assert pz.driver.seed == 7 and pz.driver.line.belt.fed == line.belt.fed


# -- SuperSuit vector path ------------------------------------------------------------------
def test_supersuit_vector_path_trains_sb3_ppo_on_the_parallel_env():
    import supersuit as ss
    from stable_baselines3 import PPO

    par = pickplace_v0.parallel_env(overrides=SHORT, render_mode="rgb_array", max_episode_steps=40)
    venv = ss.pettingzoo_env_to_vec_env_v1(par)
    venv = ss.concat_vec_envs_v1(venv, 2, num_cpus=0, base_class="stable_baselines3")
    # no seed= here: SB3 would call venv.seed(), which SuperSuit's ConcatVecEnv lacks
    model = PPO("MlpPolicy", venv, n_steps=32, batch_size=64, n_epochs=1, device="cpu")
    before = [p.detach().clone() for p in model.policy.parameters()]
    model.learn(256)
    after = list(model.policy.parameters())
    assert any(not np.allclose(a.detach(), b) for a, b in zip(after, before, strict=True))
    assert model.num_timesteps >= 256
    venv.close()
