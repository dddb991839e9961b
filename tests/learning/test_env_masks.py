"""Action masks, skipped forced NooPs, PettingZoo's own test suites and the envs' shared
conventions (issue 21)."""

from __future__ import annotations

import copy
import types

import numpy as np
import pytest
from pettingzoo.test import (
    api_test,
    max_cycles_test,
    parallel_api_test,
    parallel_seed_test,
    render_test,
    seed_test,
)
from pettingzoo.utils.conversions import parallel_to_aec

from pnp_twin.learning.envs import PickPlaceAEC, PickPlaceEnv, PickPlaceParallel, pickplace_v0
from pnp_twin.learning.envs.driver import EnvError
from pnp_twin.learning.envs.options import EnvOptions

SHORT = {"duration": 12.0, "warmup": 1.0}
KEYS = {
    "tau", "time", "picks", "noops", "deciding", "option_time", "candidates", "action_mask",
    "skipped", "gripping_rate", "line_seed",
}  # fmt: skip
pytestmark = pytest.mark.filterwarnings("ignore:Observation numpy array is all zeros")


@pytest.mark.parametrize(
    "kwargs", [{}, {"mask_in_observation": True}, {"skip_noops": True, "team_reward": True}]
)
def test_aec_passes_pettingzoo_api_and_seed_tests_with_masks(kwargs):
    api_test(PickPlaceAEC(overrides=SHORT, **kwargs), num_cycles=300)
    seed_test(lambda: PickPlaceAEC(overrides=SHORT, **kwargs), num_cycles=100)


@pytest.mark.parametrize(
    "kwargs",
    [
        {"termination": "t_all", "mask_in_observation": True},
        {"termination": "t_any", "skip_noops": True},
        {"termination": "t_continue", "skip_noops": True, "team_reward": True},
    ],
)
def test_parallel_passes_pettingzoo_api_and_seed_tests_with_masks(kwargs):
    parallel_api_test(PickPlaceParallel(overrides=SHORT, **kwargs), num_cycles=300)
    parallel_seed_test(lambda: PickPlaceParallel(overrides=SHORT, **kwargs), 80)


def test_render_test_passes_on_both_pettingzoo_envs(capsys):
    render_test(lambda render_mode: PickPlaceAEC(overrides=SHORT, render_mode=render_mode))
    render_test(
        lambda render_mode: parallel_to_aec(
            PickPlaceParallel(overrides=SHORT, render_mode=render_mode)
        )
    )
    assert "free robots" in capsys.readouterr().out  # human mode printed the text view


@pytest.mark.parametrize("skip", [False, True])
def test_max_cycles_test_passes(skip):
    mod = types.SimpleNamespace(
        env=lambda **kw: pickplace_v0.env(skip_noops=skip, **kw),
        parallel_env=lambda **kw: pickplace_v0.parallel_env(skip_noops=skip, **kw),
    )
    max_cycles_test(pickplace_v0 if not skip else mod)


def test_aec_max_cycles_caps_each_agents_decisions():
    env = PickPlaceAEC(overrides=SHORT, max_cycles=3)
    env.reset(seed=1)
    acted = dict.fromkeys(env.possible_agents, 0)
    for agent in env.agent_iter(10_000):
        _o, _r, term, trunc, _i = env.last()
        if term or trunc:
            assert trunc and not term
            env.step(None)
        else:
            acted[agent] += 1
            env.step(0)
    assert set(acted.values()) == {3}
    with pytest.raises(EnvError, match="^max_cycles: give max_cycles or max_episode_steps"):
        PickPlaceAEC(max_cycles=3, max_episode_steps=4)


def test_every_env_gives_the_same_info_keys():
    _o, info = PickPlaceEnv(overrides=SHORT).reset(seed=0)
    assert set(info) == KEYS
    aec = PickPlaceAEC(overrides=SHORT)
    aec.reset(seed=0)
    assert set(aec.infos["robot_1"]) == KEYS
    aec.step(0)
    assert all(set(i) == KEYS for i in aec.infos.values())
    par = PickPlaceParallel(overrides=SHORT)
    _o, infos = par.reset(seed=0)
    assert all(set(i) == KEYS for i in infos.values())
    infos = par.step(dict.fromkeys(par.agents, 0))[4]
    assert all(set(i) == KEYS for i in infos.values())


def test_gym_mask_marks_the_robots_with_a_choice():
    """Masked-out actions change nothing: any rule of a robot without a choice gives the
    same step as rule 0."""
    env = PickPlaceEnv(overrides=SHORT, action_type="multidiscrete")
    _o, info = env.reset(seed=5)
    rng = np.random.default_rng(0)
    forced = real = 0
    for _ in range(120):
        mask = info["action_mask"]
        assert mask.shape == (4, 5) and mask.dtype == np.int8
        for r in range(4):
            choice = r in info["deciding"] and info["candidates"][r] > 0
            assert mask[r].tolist() == ([1] * 5 if choice else [1, 0, 0, 0, 0])
        action = env.action_space.sample(tuple(mask))
        other = np.where(mask.sum(axis=1) == 1, rng.integers(5, size=4), action)
        twin = copy.deepcopy(env)
        a = env.step(action)
        b = twin.step(other)
        assert np.array_equal(a[0], b[0]) and a[1:4] == b[1:4]
        forced += int((mask.sum(axis=1) == 1).all())
        real += int((mask.sum(axis=1) > 1).any())
        info = a[4]
        if a[2] or a[3]:
            break
    assert forced > 0 and real > 0
    flat = PickPlaceEnv(overrides=SHORT)
    _o, info = flat.reset(seed=5)
    flat.step(0)
    mask = flat.action_masks()
    assert mask.shape == (625,) and mask.dtype == np.bool_ and mask.any()


def _sd_run(env, skip, seed):
    sd = env.rules.index("SD")
    _o, info = env.reset(seed=seed)
    total, steps = 0.0, 0
    while True:
        if isinstance(env, PickPlaceEnv):
            out = env.step(env.encode([sd] * env.n_robots))
            total += float(out[1])
            done = out[2] or out[3]
            info = out[4]
        else:
            out = env.step(dict.fromkeys(env.agents, sd))
            total += sum(out[1].values())
            done = not env.agents
            info = next(iter(out[4].values()))
        steps += 1
        if done:
            return total, steps, env.driver.line.recorder.picked_at, info


@pytest.mark.parametrize("cls", [PickPlaceEnv, PickPlaceParallel])
def test_skip_noops_only_removes_steps_without_a_choice(cls):
    """SD everywhere: skipping forced NooPs leaves the run and its total reward as they
    were, in fewer steps."""
    kw = {"overrides": SHORT, "termination": "t_continue", "reward_weights": (1.0, 0.0)}
    plain = _sd_run(cls(**kw), False, 3)
    skip = _sd_run(cls(skip_noops=True, **kw), True, 3)
    # the NooP penalties of the epochs reset() skips are not returned (eq. 2 weighed 0 here)
    assert np.array_equal(skip[2], plain[2], equal_nan=True)
    assert skip[0] == pytest.approx(plain[0], rel=1e-12)
    assert skip[1] < plain[1] * 0.8 and skip[3]["time"] == plain[3]["time"]


def test_aec_skip_noops_selects_only_agents_with_a_choice():
    env = PickPlaceAEC(overrides=SHORT, skip_noops=True, reward_weights=(0.0, 1.0))
    env.reset(seed=2)
    start = env.driver.now  # reset() skipped the epochs before (their penalties unreturned)
    assert start > 0.0
    total = 0.0
    for _agent in env.agent_iter(100_000):
        _o, reward, term, trunc, info = env.last()
        total += reward
        if term or trunc:
            env.step(None)
            continue
        assert info["candidates"] > 0 and info["action_mask"].sum() == 5
        env.step(3)
    spans = env.driver.line.recorder.spans_frame()
    ended = (spans["end"] > start) & (spans["end"] <= env.driver.now)
    noops = int(((spans["state"] == "noop") & ended).sum())
    assert noops > 0 and total == pytest.approx(-0.01 * noops)  # forced NooPs still count


def test_team_reward_gives_every_agent_the_sum():
    own = PickPlaceParallel(overrides=SHORT)
    shared = PickPlaceParallel(overrides=SHORT, team_reward=True)
    own.reset(seed=4)
    shared.reset(seed=4)
    for _ in range(30):
        r1 = own.step(dict.fromkeys(own.agents, 3))[1]
        r2 = shared.step(dict.fromkeys(shared.agents, 3))[1]
        assert all(v == pytest.approx(sum(r1.values())) for v in r2.values())


def test_options_live_in_one_place():
    opts = EnvOptions.make(noop_penalty=0.2)
    assert opts.noop_penalty == 0.2 and EnvOptions().noop_penalty == 0.01
    env = PickPlaceEnv(overrides=SHORT, noop_penalty=0.2)
    assert env.driver.noop_penalty == 0.2 and env.options.noop_penalty == 0.2
    with pytest.raises(EnvError, match="^noop_penaltyy: not an environment option"):
        PickPlaceEnv(noop_penaltyy=0.2)


def test_aec_tau_runs_from_the_agents_action_to_its_next_selection():
    """With skip_noops an agent's transition spans its own option and the forced NooPs
    after it: tau is the time since it acted, and the taus of an agent add up."""
    env = PickPlaceAEC(overrides=SHORT, skip_noops=True)
    env.reset(seed=6)
    acted_at = dict.fromkeys(env.possible_agents, 0.0)
    spans = dict.fromkeys(env.possible_agents, 0.0)
    for agent in env.agent_iter(100_000):
        _o, _r, term, trunc, info = env.last()
        if term or trunc:
            env.step(None)
            continue
        now = env.driver.now
        assert info["tau"] == pytest.approx(now - acted_at[agent]) and info["deciding"]
        spans[agent] += info["tau"]
        acted_at[agent] = now
        env.step(1)
    assert all(spans[a] == pytest.approx(acted_at[a]) for a in spans)
    assert max(acted_at.values()) > 6.0
