"""The PettingZoo environments: AEC (asynchronous) and Parallel (synchronous)."""

from __future__ import annotations

import numpy as np
import pytest
from pettingzoo.test import api_test, parallel_api_test, parallel_seed_test, seed_test

from pnp_twin.learning.envs import PickPlaceAEC, PickPlaceParallel

SHORT = {"duration": 12.0, "warmup": 1.0}


# The belt is empty at t = 0, so the first observation is all zeros: true, not a fault.
@pytest.mark.filterwarnings("ignore:Observation numpy array is all zeros")
def test_aec_passes_the_api_and_seed_tests():
    env = PickPlaceAEC(overrides=SHORT)
    api_test(env, num_cycles=400)
    seed_test(lambda: PickPlaceAEC(overrides=SHORT), num_cycles=200)


def test_aec_plays_a_whole_episode_to_termination():
    env = PickPlaceAEC(overrides=SHORT)
    env.reset(seed=0)
    finished = []
    for agent in env.agent_iter(100_000):
        _obs, _r, term, trunc, _info = env.last()
        if term or trunc:
            assert term and not trunc
            finished.append(agent)
            env.step(None)
        else:
            env.step(0)
    assert sorted(finished) == ["robot_1", "robot_2", "robot_3", "robot_4"]
    assert env.agents == [] and env.driver.now >= 12.0


@pytest.mark.parametrize("scheme", ["t_all", "t_any"])
def test_parallel_passes_the_api_and_seed_tests(scheme):
    parallel_api_test(PickPlaceParallel(overrides=SHORT, termination=scheme), num_cycles=400)
    parallel_seed_test(lambda: PickPlaceParallel(overrides=SHORT, termination=scheme), 100)


def test_aec_selects_the_free_robot_and_credits_option_rewards():
    """agent_selection is a robot free now; rewards and tau are its ended options'."""
    env = PickPlaceAEC(overrides=SHORT, reward_weights=(1.0, 0.0))
    env.reset(seed=3)
    rng = np.random.default_rng(0)
    driver = env.driver
    credited = dict.fromkeys(env.possible_agents, 0.0)
    taus = []
    for agent in env.agent_iter(100_000):
        obs, reward, term, trunc, info = env.last()
        credited[agent] += reward
        if term or trunc:
            env.step(None)
            continue
        robot = env.possible_agents.index(agent)
        assert robot in driver.deciding
        assert robot in driver.line.gateway.pending
        assert obs.shape == (1, 8, driver.camera.window_width)
        option = driver.option(robot)
        if option is not None:
            assert info["tau"] == option.duration
            taus.append(info["tau"])
        env.step(int(rng.integers(5)))
    # robot r's eq. 1 rewards: 1 / (placed - decided) for each of its parts placed by the end
    line = driver.line
    parts = line.recorder.parts_frame(line.belt, line.last_end)
    done = parts[parts["placed_at"] <= driver.now]
    for r, agent in enumerate(env.possible_agents):
        mine = done[done["robot"] == r + 1]  # the records number robots from 1
        expected = float((1.0 / (mine["placed_at"] - mine["decided_at"])).sum())
        assert expected > 0 and credited[agent] == pytest.approx(expected, rel=1e-9)
    assert min(taus) > 0.0


def test_aec_noop_penalty_is_credited_per_noop():
    env = PickPlaceAEC(overrides=SHORT, reward_weights=(0.0, 1.0), noop_penalty=0.5)
    env.reset(seed=8)
    total = 0.0
    for _agent in env.agent_iter(100_000):
        _obs, reward, term, trunc, _info = env.last()
        total += reward
        env.step(None if term or trunc else 3)
    spans = env.driver.line.recorder.spans_frame()
    noops = int(((spans["state"] == "noop") & (spans["end"] <= env.driver.now)).sum())
    assert noops > 0 and total == pytest.approx(-0.5 * noops)


def test_parallel_t_all_every_robot_decides_every_step():
    env = PickPlaceParallel(overrides=SHORT)
    obs, infos = env.reset(seed=2)
    assert set(obs) == set(env.possible_agents)
    steps = 0
    while env.agents:
        actions = {a: 3 for a in env.agents}
        obs, rewards, terms, truncs, infos = env.step(actions)
        steps += 1
        assert all(info["deciding"] for info in infos.values())
        taus = {info["tau"] for info in infos.values()}
        assert len(taus) == 1 and taus.pop() > 0
        for a, info in infos.items():
            assert info["option_time"] == info["tau"]
            assert np.isfinite(rewards[a])
        window = obs["robot_2"]
        s = env.driver.camera.starts[1]
        full = env.state()
        assert np.array_equal(window, full[:, :, s : s + window.shape[2]])
    assert all(terms.values()) and steps > 10


def test_parallel_t_any_busy_robots_keep_their_option():
    env = PickPlaceParallel(overrides=SHORT, termination="t_any")
    env.reset(seed=4)
    partial = 0
    while env.agents:
        before = list(env.driver.deciding)
        _obs, rewards, _t, _tr, infos = env.step({a: 1 for a in env.agents})
        deciding = [r for r, a in enumerate(env.possible_agents) if infos[a]["deciding"]]
        assert deciding == env.driver.deciding
        partial += len(before) < 4
        for r, a in enumerate(env.possible_agents):
            if r not in deciding:
                assert rewards[a] == 0.0 and infos[a]["option_time"] == 0.0
    assert partial > 0  # some epochs leave a placing robot out


def test_bad_action_is_a_one_line_error():
    env = PickPlaceAEC(overrides=SHORT)
    env.reset(seed=0)
    with pytest.raises(Exception, match=r"^action: 9 for robot_1 is not in 0\.\.4$"):
        env.step(9)
