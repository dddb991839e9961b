"""The multi-agent mode of the compiled vector env (``PickPlaceParallelVectorEnv``) against
``PickPlaceParallel`` envs of the SimPy twin: the same seeds and actions give the same steps,
agent for agent, across autoresets."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from pnp_twin.learning.envs import PickPlaceParallel
from pnp_twin.learning.envs.vector_marl import PickPlaceParallelVectorEnv

SHORT = {"duration": 6.0, "warmup": 1.0}
CASES: dict[str, dict[str, Any]] = {
    "t_all_team_caps": dict(overrides=SHORT, channels=2, team_reward=True, max_cycles=60),
    "t_continue_skip_siro": dict(
        overrides=SHORT,
        termination="t_continue",
        rules=("SIRO", "SD", "SPT"),
        skip_noops=True,
        channels=3,
    ),
    "t_any_breakdowns_time_cap": dict(
        scenario="breakdowns",
        overrides={"duration": 10.0, "warmup": 1.0, "robots.mtbf": 2.0, "robots.mttr": 0.7},
        termination="t_any",
        max_episode_time=7.0,
        observation="image",
    ),
}
PER_AGENT = ("deciding", "picks", "noops", "option_time", "candidates")
PER_LINE = ("tau", "time", "skipped", "gripping_rate", "line_seed")


class Reference:
    """``n`` PickPlaceParallel envs with the vector env's seeding and NEXT_STEP autoreset."""

    def __init__(self, n: int, kwargs: dict[str, Any]) -> None:
        self.envs = [PickPlaceParallel(**kwargs) for _ in range(n)]
        self.ended = [False] * n

    def reset(self, seed: int) -> tuple[Any, ...]:
        out = [env.reset(seed=seed + e) for e, env in enumerate(self.envs)]
        self.ended = [False] * len(self.envs)
        return self._batch([(o, None, False, False, i) for o, i in out])

    def step(self, actions: np.ndarray) -> tuple[Any, ...]:
        out: list[Any] = []
        for e, env in enumerate(self.envs):
            if self.ended[e]:
                obs, infos = env.reset()
                out.append((obs, None, False, False, infos))
                self.ended[e] = False
                continue
            agents = env.possible_agents
            obs, rew, term, trunc, infos = env.step(
                {a: int(actions[e, i]) for i, a in enumerate(agents)}
            )
            t, tr = term[agents[0]], trunc[agents[0]]
            self.ended[e] = t or tr
            out.append((obs, [rew[a] for a in agents], t, tr, infos))
        return self._batch(out)

    def _batch(self, out: list[Any]) -> tuple[Any, ...]:
        agents = self.envs[0].possible_agents
        obs = np.stack([np.stack([o[a] for a in agents]) for o, *_ in out])
        rew = np.array([r if r is not None else [0.0] * len(agents) for _, r, *_ in out])
        term = np.array([t for _, _, t, _, _ in out])
        trunc = np.array([t for _, _, _, t, _ in out])
        info: dict[str, Any] = {}
        for key in PER_AGENT:
            info[key] = np.array([[i[a][key] for a in agents] for *_, i in out])
        info["action_mask"] = np.array([[i[a]["action_mask"] for a in agents] for *_, i in out])
        for key in PER_LINE:
            info[key] = np.array([i[agents[0]][key] for *_, i in out])
        state = np.stack([env.state() for env in self.envs])
        return obs, rew, term, trunc, info, state


@pytest.mark.parametrize("case", sorted(CASES))
def test_steps_match_parallel_envs_agent_for_agent(case: str) -> None:
    kwargs, n, seed = CASES[case], 3, 7
    fast = PickPlaceParallelVectorEnv(num_envs=n, **kwargs)
    ref = Reference(n, kwargs)
    obs_f, info_f = fast.reset(seed=seed)
    obs_r, *_rest, info_r, state_r = ref.reset(seed)
    np.testing.assert_array_equal(obs_f, obs_r)
    rng = np.random.default_rng(seed)
    ended = rewarded = forced = 0
    for step in range(250):
        actions = rng.integers(len(fast.rules), size=(n, fast.n_agents))
        got = fast.step(actions)
        want = ref.step(actions)
        for name, a, b in zip(
            ("obs", "rewards", "terminated", "truncated"), got, want, strict=False
        ):
            np.testing.assert_array_equal(a, b, err_msg=f"{name} at step {step}")
        for key in (*PER_AGENT, *PER_LINE, "action_mask"):
            np.testing.assert_array_equal(got[4][key], want[4][key], err_msg=f"{key} {step}")
        np.testing.assert_array_equal(fast.state(), want[5])
        ended += int((got[2] | got[3]).sum())
        rewarded += int((got[1] != 0).sum())
        forced += int((got[4]["candidates"] == 0).sum())
    assert ended >= n and rewarded > 0 and forced > 0
    assert obs_f.shape[:2] == (n, 4) and fast.single_observation_space.contains(obs_f[0, 0])


def test_team_rewards_are_the_sum_of_the_agents():
    own = PickPlaceParallelVectorEnv(num_envs=2, overrides=SHORT)
    team = PickPlaceParallelVectorEnv(num_envs=2, overrides=SHORT, team_reward=True)
    own.reset(seed=1)
    team.reset(seed=1)
    for _ in range(20):
        a = np.full((2, 4), 3)
        r_own = own.step(a)[1]
        r_team = team.step(a)[1]
        np.testing.assert_array_equal(r_team, np.repeat(r_own.sum(axis=1)[:, None], 4, axis=1))
        np.testing.assert_array_equal(own.team_rewards, r_own.sum(axis=1))
