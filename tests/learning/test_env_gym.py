"""The epoch driver and the Gymnasium env ``pnp_twin/PickPlace-v0``."""

from __future__ import annotations

import math
import pickle
from bisect import bisect_left, bisect_right

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

from pnp_twin.learning.envs import ENV_ID, EnvError, EpochDriver, PickPlaceEnv, make_env
from pnp_twin.policies import make_policy
from pnp_twin.twin.loader import load_scenario
from pnp_twin.twin.run import simulate

SHORT = {"duration": 20.0, "warmup": 1.0}


def make_short():
    return load_scenario("paper_baseline", SHORT)


def rollout(env: gym.Env, seed: int, steps: int, action_seed: int = 0) -> list[tuple]:
    rng = np.random.default_rng(action_seed)
    obs, info = env.reset(seed=seed)
    out = [(obs.tobytes(), 0.0, info["time"], tuple(info["deciding"]))]
    for _ in range(steps):
        obs, r, term, trunc, info = env.step(int(rng.integers(env.action_space.n)))
        out.append((obs.tobytes(), r, info["time"], tuple(info["deciding"]), term, trunc))
        if term or trunc:
            break
    return out


def test_check_env_passes_and_spaces_follow_the_scenario():
    env = PickPlaceEnv(overrides=SHORT)
    check_env(env, skip_render_check=True)
    assert env.observation_space.shape == (1, 8, 64)
    assert env.observation_space.dtype == np.uint8
    assert env.action_space.n == 5**4
    multi = PickPlaceEnv(overrides=SHORT, action_type="multidiscrete", channels=3)
    check_env(multi, skip_render_check=True)
    assert list(multi.action_space.nvec) == [5, 5, 5, 5]
    assert multi.observation_space.shape == (3, 8, 64)


def test_registered_id_builds_from_a_scenario_object_with_overrides(make_scenario):
    scenario = make_scenario({"robots.count": 2})
    env = gym.make(ENV_ID, scenario=scenario, overrides={"feeder.rate": 6}, rules=["SPT", "FIFO"])
    assert env.unwrapped.scenario.feeder.rate == 6
    assert env.action_space.n == 2**2
    obs, info = env.reset(seed=3)
    assert obs.shape == (1, 8, 64) and info["deciding"] == [0, 1]


def test_same_seed_same_rollout_other_seed_differs():
    env = PickPlaceEnv(overrides=SHORT)
    a = rollout(env, seed=11, steps=150)
    b = rollout(PickPlaceEnv(overrides=SHORT), seed=11, steps=150)
    c = rollout(env, seed=12, steps=150)
    assert a == b
    assert a != c


@pytest.mark.parametrize("scheme", ["t_continue", "t_all", "t_any"])
def test_driver_leaves_the_twin_unchanged(make_scenario, scheme):
    """Answering every epoch with SD reproduces simulate() with SD, part for part."""
    scenario = make_scenario(termination=scheme, duration=15.0)
    driver = EpochDriver(scenario)
    deciding = driver.reset(4)
    while not driver.done:
        deciding = driver.act(dict.fromkeys(deciding, driver.rules.index("SD")))
    ref = simulate(scenario, make_policy("SD"), seed=4).parts
    belt, now = driver.line.belt, driver.now
    passed = bisect_right(belt.fed, now - driver.line.last_end / belt.speed)
    assert passed > 50
    mine = np.array(driver.line.recorder.picked_at[:passed])
    theirs = ref["picked_at"].to_numpy()[:passed]
    assert np.array_equal(mine, theirs, equal_nan=True)
    # the gripping rate counts the command line's window: parts fed after the warm-up
    first = bisect_left(belt.fed, scenario.warmup)
    picked = int(np.isfinite(mine[first:]).sum())
    assert driver.gripping_rate() == pytest.approx(100.0 * picked / (passed - first))


def test_rewards_match_the_records():
    """Sum of eq. 1 over steps = sum over ended pick options of 1 / (placed - decided)."""
    env = PickPlaceEnv(overrides=SHORT, reward_weights=(1.0, 1.0), noop_penalty=0.05)
    env.reset(seed=2)
    rng = np.random.default_rng(1)
    total, picks, ended_noops = 0.0, np.zeros(4, dtype=int), 0
    term = trunc = False
    while not (term or trunc):
        _obs, r, term, trunc, info = env.step(int(rng.integers(env.action_space.n)))
        total += r
        picks += info["picks"]
        for robot in info["deciding"]:
            o = env.driver.option(robot)
            ended_noops += o.noop
            assert info["option_time"][robot] == o.duration
    assert term and not trunc and info["time"] >= 20.0
    now = env.driver.now
    line = env.driver.line
    parts = line.recorder.parts_frame(line.belt, line.last_end)
    done = parts[parts["placed_at"] <= now]
    extrinsic = float((1.0 / (done["placed_at"] - done["decided_at"])).sum())
    spans = line.recorder.spans_frame()
    noops = int(((spans["state"] == "noop") & (spans["end"] <= now)).sum())
    assert noops == ended_noops and noops > 0
    assert total == pytest.approx(extrinsic - 0.05 * noops, rel=1e-9)
    # info["picks"] counts every completed grip, per robot
    gripped = parts[parts["robot"].notna()]
    assert picks.tolist() == [int((gripped["robot"] == r + 1).sum()) for r in range(4)]
    assert info["gripping_rate"] == pytest.approx(env.driver.gripping_rate())


def test_joint_action_robot_one_is_the_most_significant_digit():
    env = PickPlaceEnv(overrides=SHORT)
    assert env.decode(1 * 125 + 2 * 25 + 3 * 5 + 4) == [1, 2, 3, 4]
    assert env.encode([4, 0, 0, 1]) == 4 * 125 + 1
    env.reset(seed=0)
    rules = env.rules
    action = env.encode([1, 3, 4, 0])  # LIFO, SD, LD, FIFO
    for _ in range(200):
        env.step(action)
    rec = env.driver.line.recorder
    used = {(r, rule) for r, rule in zip(rec.robot, rec.rule, strict=True) if r >= 0}
    assert used == {(0, rules[1]), (1, rules[3]), (2, rules[4]), (3, rules[0])}


def test_observation_is_the_belt_image_with_documented_channels():
    env = PickPlaceEnv(overrides=SHORT, channels=3, termination="t_continue")
    env.reset(seed=5)
    driver = env.driver
    camera = driver.camera
    seen_claim = False
    for step in range(300):
        obs, _r, term, trunc, _i = env.step(step % env.action_space.n)
        if term or trunc:  # stepping past the end raises
            obs, _i = env.reset()
        line = driver.line
        assert np.array_equal(obs[0], line.belt.image(driver.now))
        assert (obs[1] <= obs[0]).all()
        seen_claim |= bool(obs[1].any())
        free = set(driver.deciding)
        for robot, (s, e) in enumerate(camera.spans):
            if robot not in free:
                assert obs[2, :, s:e].all()
            else:
                others = [camera.spans[o] for o in range(4) if o not in free]
                cols = [c for c in range(s, e) if not any(a <= c < b for a, b in others)]
                assert not obs[2][:, cols].any()
        window = driver.observe(2)
        s = camera.starts[2]
        assert np.array_equal(window, obs[:, :, s : s + camera.window_width])
    assert seen_claim


def test_episode_ends_by_time_or_by_steps():
    env = PickPlaceEnv(overrides={"duration": 5.0, "warmup": 1.0}, max_episode_steps=10_000)
    env.reset(seed=0)
    steps, term, trunc = 0, False, False
    while not (term or trunc):
        _o, _r, term, trunc, info = env.step(0)
        steps += 1
    assert term and not trunc and info["time"] >= 5.0 and steps < 10_000
    env = PickPlaceEnv(overrides=SHORT, max_episode_steps=7)
    env.reset(seed=0)
    flags = [env.step(0)[2:4] for _ in range(7)]
    assert flags[:-1] == [(False, False)] * 6 and flags[-1] == (False, True)


def test_tau_is_the_simulated_time_of_the_step():
    env = PickPlaceEnv(overrides=SHORT, termination="t_all")
    _obs, info = env.reset(seed=1)
    before = info["time"]
    for _ in range(20):
        _o, _r, _t, _tr, info = env.step(0)
        assert info["tau"] == pytest.approx(info["time"] - before)
        assert info["tau"] > 0 and info["deciding"] == [0, 1, 2, 3]
        before = info["time"]


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [
        ({"action_type": "box"}, "action_type"),
        ({"termination": "t_some"}, "termination"),
        ({"rules": ["FIFO", "EDD"]}, "rules"),
        ({"channels": 4}, "channels"),
        ({"overrides": {"robots.count": 0}}, "robots.count"),
    ],
)
def test_bad_arguments_raise_one_line_errors(kwargs, field):
    with pytest.raises(EnvError if field != "robots.count" else Exception) as e:
        PickPlaceEnv(**kwargs)
    assert str(e.value).startswith(field) and "\n" not in str(e.value)


def test_out_of_range_actions_are_one_line_errors():
    env = PickPlaceEnv(overrides=SHORT)
    env.reset(seed=0)
    with pytest.raises(EnvError, match=r"^action: 625 is not in 0\.\.624$"):
        env.step(625)
    with pytest.raises(EnvError, match=r"^action: -1 is not"):
        env.step(-1)
    multi = PickPlaceEnv(overrides=SHORT, action_type="multidiscrete")
    multi.reset(seed=0)
    with pytest.raises(EnvError, match="one rule index in 0..4 per robot"):
        multi.step([0, 1, 5, 0])
    driver = EpochDriver(make_short())
    deciding = driver.reset(0)
    with pytest.raises(EnvError, match=r"rule index 7 for robot 0 is not in 0\.\.4"):
        driver.act(dict.fromkeys(deciding, 7))


def test_factory_is_picklable_and_drives_an_async_vector_env():
    factory = make_env(overrides=SHORT, max_episode_steps=50)
    clone = pickle.loads(pickle.dumps(factory))
    assert isinstance(clone(), PickPlaceEnv)
    venv = gym.vector.AsyncVectorEnv([factory, factory])
    try:
        obs, _info = venv.reset(seed=[3, 4])
        actions = [[7, 9], [100, 3], [0, 0]]
        vec = [obs[0]]
        for a in actions:
            obs, rewards, _t, _tr, _i = venv.step(np.array(a))
            assert np.isfinite(rewards).all()
            vec.append(obs[0])
    finally:
        venv.close()
    single = factory()
    ref = [single.reset(seed=3)[0]] + [single.step(a[0])[0] for a in actions]
    assert all(np.array_equal(x, y) for x, y in zip(vec, ref, strict=True))
    assert not math.isnan(float(np.asarray(vec).sum()))
