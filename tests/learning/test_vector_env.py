"""``PickPlaceVectorEnv`` (the compiled engine) against ``SyncVectorEnv`` of ``PickPlaceEnv``
(the SimPy twin): the same seeds and actions give the same steps, across autoresets."""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.vector import AutoresetMode

from pnp_twin.learning.envs import ENV_ID, MAX_EPISODE_STEPS, EnvError, PickPlaceEnv
from pnp_twin.learning.envs.vector_env import PickPlaceVectorEnv
from pnp_twin.learning.vector import batch
from pnp_twin.policies.rules import PAPER_RULES
from pnp_twin.twin.fast import layout as L

SHORT = {"duration": 6.0, "warmup": 1.0}

CASES: dict[str, dict[str, Any]] = {
    "t_continue_caps": dict(
        overrides=SHORT, termination="t_continue", channels=3, max_episode_steps=70
    ),
    "t_all_breakdowns": dict(
        scenario="breakdowns",
        overrides={"duration": 12.0, "warmup": 1.0, "robots.mtbf": 2.0, "robots.mttr": 0.7},
        termination="t_all",
        channels=2,
        action_type="multidiscrete",
        rules=("SIRO", "SPT", "LD"),
    ),
    "t_any_bins": dict(
        overrides={**SHORT, "bins.capacity": 3, "bins.change_time": 0.4},
        termination="t_any",
        channels=1,
        rules=("SIRO", "SD", "LIFO", "SPT"),
        reward_weights=(0.5, 2.0),
        noop_penalty=0.1,
    ),
    "t_continue_time_cap_bins_breakdowns": dict(
        scenario="two_robot",
        overrides={
            "duration": 9.0,
            "warmup": 1.0,
            "bins.capacity": 2,
            "bins.change_time": 0.3,
            "robots.mtbf": 1.5,
            "robots.mttr": 0.5,
        },
        channels=3,
        max_episode_time=4.0,
        rules=PAPER_RULES,
    ),
    "t_any_trace_acceleration": dict(
        scenario="trace_replay",
        overrides={"duration": 8.0, "warmup": 1.0, "robots.acceleration": 12.0},
        termination="t_any",
        channels=3,
        action_type="multidiscrete",
        rules=("SPT", "SIRO"),
    ),
    "t_continue_skip_noops_caps": dict(
        overrides={**SHORT, "warmup": 2.0},
        termination="t_continue",
        rules=("SIRO", "SD", "FIFO"),
        max_episode_steps=40,
        skip_noops=True,
    ),
    "t_any_skip_noops_breakdowns_time_cap": dict(
        scenario="breakdowns",
        overrides={"duration": 12.0, "warmup": 1.0, "robots.mtbf": 2.0, "robots.mttr": 0.7},
        termination="t_any",
        action_type="multidiscrete",
        rules=("SIRO", "LD"),
        max_episode_time=9.0,
        skip_noops=True,
        threads=2,  # the same steps on two threads as on one (the default)
    ),
}


def _lists_to_array(values: np.ndarray, n_robots: int, fill: float = 0.0) -> np.ndarray:
    """SyncVectorEnv's object array of per-env lists as one (envs, robots) array."""
    return np.array([list(v) if v is not None else [fill] * n_robots for v in values])


def assert_infos_match(fast: dict[str, Any], simpy: dict[str, Any], n_robots: int) -> None:
    assert set(fast) == set(simpy)
    for key in ("time", "tau", "gripping_rate", "line_seed", "skipped"):
        np.testing.assert_array_equal(fast[key], simpy[key], err_msg=key)
    deciding = np.zeros_like(fast["deciding"])
    for e, robots in enumerate(simpy["deciding"]):
        deciding[e, robots] = True
    np.testing.assert_array_equal(fast["deciding"], deciding)
    for key in ("picks", "noops", "option_time", "candidates"):
        want = _lists_to_array(simpy[key], n_robots)
        np.testing.assert_array_equal(fast[key], want, err_msg=key)
    masks = np.stack([np.asarray(m) for m in simpy["action_mask"]])
    np.testing.assert_array_equal(fast["action_mask"], masks, err_msg="action_mask")


def run_both(kwargs: dict[str, Any], n_envs: int, steps: int, seed: int) -> dict[str, int]:
    """Step both vector envs with the same random actions; returns what was covered."""
    fast = PickPlaceVectorEnv(num_envs=n_envs, **kwargs)
    kwargs = {k: v for k, v in kwargs.items() if k != "threads"}
    simpy: Any = gym.vector.SyncVectorEnv([lambda: PickPlaceEnv(**kwargs) for _ in range(n_envs)])
    assert fast.single_action_space == simpy.single_action_space
    assert fast.single_observation_space == simpy.single_observation_space
    obs_f, info_f = fast.reset(seed=seed)
    obs_s, info_s = simpy.reset(seed=seed)
    np.testing.assert_array_equal(obs_f, obs_s)
    n_robots = fast.n_robots
    assert_infos_match(info_f, info_s, n_robots)
    rng = np.random.default_rng(seed)
    seen = dict.fromkeys(
        ("terminated", "truncated", "reward", "siro", "down", "boxes", "skipped", "forced"), 0
    )
    for step in range(steps):
        if kwargs.get("action_type") == "multidiscrete":
            actions = rng.integers(len(fast.rules), size=(n_envs, n_robots))
        else:
            actions = rng.integers(len(fast.rules) ** n_robots, size=n_envs)
        got = fast.step(actions)
        want = simpy.step(actions)
        for name, a, b in zip(
            ("obs", "reward", "terminated", "truncated"), got, want, strict=False
        ):
            np.testing.assert_array_equal(a, b, err_msg=f"{name} at step {step}")
        assert_infos_match(got[4], want[4], n_robots)
        seen["terminated"] += int(got[2].sum())
        seen["truncated"] += int(got[3].sum())
        seen["reward"] += int((got[1] != 0).sum())
        ist, gs = fast.batch.ist, fast.batch.gs
        seen["siro"] += int((gs[:, L.SIROIDX] > 0).sum())  # SIRO drew (not all-FIFO luck)
        seen["down"] += int(ist[:, :, L.DOWN].sum())  # robots down at this epoch
        seen["boxes"] += int((ist[:, :, L.BOXES] > 0).sum())  # boxes changed so far
        seen["skipped"] += int(got[4]["skipped"].sum())
        seen["forced"] += int((got[4]["candidates"].sum(axis=1) == 0).sum())
    return seen


@pytest.mark.parametrize("case", sorted(CASES))
def test_steps_match_the_simpy_vector_env_across_autoresets(case: str) -> None:
    seen = run_both(CASES[case], n_envs=4, steps=400, seed=11)
    assert seen["reward"] > 0
    assert seen["terminated"] + seen["truncated"] >= 3  # every env ended at least once
    assert seen["siro"] > 0
    assert seen["truncated"] > 0 if "caps" in case or "time_cap" in case else True
    assert seen["down"] > 0 if "breakdowns" in case else seen["down"] == 0
    assert seen["boxes"] > 0 if "bins" in case else seen["boxes"] == 0
    if "skip_noops" in case:  # epochs without a choice were skipped, never returned
        assert seen["skipped"] > 0 and seen["forced"] <= seen["terminated"] + seen["truncated"]
    else:
        assert seen["skipped"] == 0 and seen["forced"] > 0


def test_streams_topped_up_and_parts_room_grown_give_the_same_steps(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Tiny pre-drawn streams (refilled every few steps) and too little room for parts
    (grown at the first load) change nothing."""
    monkeypatch.setattr(batch, "SIRO_ROOM", 24)
    monkeypatch.setattr(batch, "SIRO_MARGIN", 8)
    monkeypatch.setattr(batch, "EXP_ROOM", 10)
    monkeypatch.setattr(batch, "EXP_MARGIN", 4)
    monkeypatch.setattr(batch, "PARTS_SLACK", 0.5)
    monkeypatch.setattr(batch, "PARTS_PAD", 0)
    kwargs: dict[str, Any] = {
        **CASES["t_continue_time_cap_bins_breakdowns"],
        "rules": ("SIRO", "SD"),
    }
    seen = run_both(kwargs, n_envs=2, steps=150, seed=5)
    assert seen["truncated"] > 0


def test_a_line_reset_with_its_old_streams_nearly_used_starts_its_new_streams_afresh(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """SIRO only, a tiny room: at most autoresets the old stream is past the margin."""
    monkeypatch.setattr(batch, "SIRO_ROOM", 12)
    monkeypatch.setattr(batch, "SIRO_MARGIN", 6)
    monkeypatch.setattr(batch, "EXP_ROOM", 6)
    monkeypatch.setattr(batch, "EXP_MARGIN", 3)
    kwargs: dict[str, Any] = {
        **CASES["t_continue_time_cap_bins_breakdowns"],
        "rules": ("SIRO",),
        "max_episode_time": 1.5,
    }
    seen = run_both(kwargs, n_envs=3, steps=150, seed=8)
    assert seen["truncated"] >= 6


def test_a_stream_running_dry_within_a_step_fails_in_one_line(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.setattr(batch, "SIRO_ROOM", 3)
    monkeypatch.setattr(batch, "SIRO_MARGIN", 0)
    env = PickPlaceVectorEnv(num_envs=2, overrides=SHORT, rules=("SIRO",), max_episode_steps=None)
    env.reset(seed=0)
    with pytest.raises(batch.StreamsExhausted, match="ran out"):
        for _ in range(200):
            env.step(np.zeros(2, dtype=np.int64))


def test_image_observations_and_line_seed_option_match() -> None:
    kwargs: dict[str, Any] = dict(overrides=SHORT, observation="image", channels=2)
    fast = PickPlaceVectorEnv(num_envs=2, **kwargs)
    simpy: Any = gym.vector.SyncVectorEnv([lambda: PickPlaceEnv(**kwargs) for _ in range(2)])
    obs_f, info_f = fast.reset(seed=1, options={"line_seed": 42})
    obs_s, _ = simpy.reset(seed=1, options={"line_seed": 42})
    assert list(info_f["line_seed"]) == [42, 42]
    np.testing.assert_array_equal(obs_f, obs_s)
    for a in ([3, 600], [0, 1], [624, 7]):
        np.testing.assert_array_equal(fast.step(np.array(a))[0], simpy.step(np.array(a))[0])
    assert fast.observation_space.contains(obs_f)


def test_reset_mask_resets_only_the_masked_envs() -> None:
    fast = PickPlaceVectorEnv(num_envs=3, overrides=SHORT)
    fast.reset(seed=2)
    for _ in range(5):
        fast.step(np.array([1, 2, 3]))
    before = fast.batch.now.copy()
    obs, info = fast.reset(seed=[None, 9, None], options={"reset_mask": np.array([0, 1, 0], bool)})
    assert fast.batch.now[1] == 0.0 and fast.batch.now[0] == before[0]
    assert list(info["_time"]) == [False, True, False]
    single = PickPlaceEnv(overrides=SHORT)
    np.testing.assert_array_equal(obs[1], single.reset(seed=9)[0])
    assert info["line_seed"][1] == single.driver.seed


def test_spaces_metadata_and_make_vec() -> None:
    env = gym.make_vec(ENV_ID, num_envs=4, vectorization_mode="vector_entry_point", channels=2)
    assert isinstance(env, PickPlaceVectorEnv)
    assert env.metadata["autoreset_mode"] == AutoresetMode.NEXT_STEP
    assert env.batch.ei[0] == MAX_EPISODE_STEPS  # the spec's step cap
    assert env.single_observation_space == gym.spaces.Box(0, 1, (2, 8, 64), np.uint8)
    assert env.observation_space.shape == (4, 2, 8, 64)
    assert env.single_action_space == gym.spaces.Discrete(5**4)
    assert env.action_space == gym.spaces.MultiDiscrete([5**4] * 4)
    multi = PickPlaceVectorEnv(num_envs=3, action_type="multidiscrete", overrides=SHORT)
    assert multi.action_space.shape == (3, 4)
    assert gym.make_vec(ENV_ID, num_envs=2, vectorization_mode="sync").num_envs == 2


def test_checker_style_seeding_types_and_spaces() -> None:
    """What gymnasium.utils.env_checker checks, as it applies to a vector env."""
    env = PickPlaceVectorEnv(num_envs=3, overrides=SHORT, channels=3)
    env.action_space.seed(0)
    obs_a, info_a = env.reset(seed=123)
    actions = [env.action_space.sample() for _ in range(20)]
    run_a = [env.step(a) for a in actions]
    obs_b, info_b = env.reset(seed=123)
    run_b = [env.step(a) for a in actions]
    np.testing.assert_array_equal(obs_a, obs_b)
    np.testing.assert_equal(run_a, run_b)  # exact
    np.testing.assert_equal(info_a, info_b)
    other = env.reset(seed=124)[1]["line_seed"]  # env i is seeded with seed + i
    assert other[0] != info_a["line_seed"][0]
    np.testing.assert_array_equal(other[:2], info_a["line_seed"][1:])
    obs, reward, term, trunc, info = run_a[-1]
    assert env.observation_space.contains(obs) and obs.dtype == np.uint8
    assert reward.dtype == np.float64 and reward.shape == (3,)
    assert term.dtype == np.bool_ and trunc.dtype == np.bool_
    assert info["deciding"].shape == (3, 4) and info["deciding"].dtype == np.bool_
    assert obs is not env.step(env.action_space.sample())[0]  # copies by default
    env.close()
    shared = PickPlaceVectorEnv(num_envs=2, overrides=SHORT, copy=False)
    first, _ = shared.reset(seed=0)
    assert shared.step(np.array([1, 2]))[0] is first  # the one buffer, written in place


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"num_envs": 0}, "num_envs: 0 is not allowed"),
        ({"action_type": "box"}, "action_type: 'box' is not allowed"),
        ({"channels": 4}, "channels: 4 is not allowed; give 1 to 3"),
        ({"rules": ("FIFO", "NOPE")}, "rules:"),
        ({"termination": "never"}, "termination: 'never' is not a scheme"),
        ({"max_episode_steps": 0}, "max_episode_steps: 0 is not allowed"),
        ({"max_episode_time": -1.0}, "max_episode_time: -1.0 is not allowed"),
        ({"observation": "rgb"}, "observation: 'rgb' is not allowed"),
        ({"reward_weights": (1.0,)}, "reward_weights: give two finite numbers"),
        ({"threads": 0}, "threads: 0 is not allowed; give 1 to"),
        ({"noop_penalti": 0.1}, "noop_penalti: not an environment option"),
        ({"render_mode": "human"}, "render_mode: 'human' is not allowed"),
    ],
)
def test_bad_arguments_fail_in_one_line(kwargs: dict[str, Any], match: str) -> None:
    with pytest.raises(EnvError, match=match) as info:
        PickPlaceVectorEnv(**{"overrides": SHORT, **kwargs})
    assert "\n" not in str(info.value)


def test_bad_actions_seeds_and_calls_fail_in_one_line() -> None:
    env = PickPlaceVectorEnv(num_envs=2, overrides=SHORT)
    with pytest.raises(EnvError, match="call reset"):
        env.step(np.zeros(2, dtype=np.int64))
    with pytest.raises(EnvError, match="seed: 3 seeds given for 2 envs"):
        env.reset(seed=[1, 2, 3])
    with pytest.raises(EnvError, match="first reset must reset every env"):
        env.reset(options={"reset_mask": np.array([True, False])})
    env.reset(seed=0)
    with pytest.raises(EnvError, match=r"actions: give 2 integers in 0\.\.624"):
        env.step(np.array([0, 625]))
    with pytest.raises(EnvError, match="actions:"):
        env.step(np.array([0.5, 1.0]))
    with pytest.raises(EnvError, match="options: line_seed -1 is not allowed"):
        env.reset(options={"line_seed": -1})
