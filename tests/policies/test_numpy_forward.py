"""The learned policy's numpy forward pass: the greedy action is torch's, proven by the
bound it carries, on many observations; near ties and networks it does not run go to
torch; a run's decisions are the same either way."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

torch = pytest.importorskip("torch")
pytest.importorskip("safetensors")
torch.set_num_threads(1)

from pnp_twin.policies.hdqn.agent import AgentConfig, QAgent  # noqa: E402
from pnp_twin.policies.hdqn.numpy_forward import NumpyQ, Unsupported  # noqa: E402
from pnp_twin.policies.hdqn.policy import HDQNPolicy  # noqa: E402
from pnp_twin.twin import load_scenario, with_overrides  # noqa: E402
from pnp_twin.twin.run import simulate  # noqa: E402

MODELS = Path(__file__).resolve().parents[2] / "models"


def observations(agent: QAgent, n: int, seed: int) -> tuple[np.ndarray, np.ndarray | None]:
    rng = np.random.default_rng(seed)
    density = rng.uniform(0.0, 0.4, (n, 1, 1, 1))
    obs = (rng.random((n, *agent.obs_shape)) < density).astype(np.uint8)
    extra = None
    if agent.n_extra and agent.obs_shape[0] == 0:  # a student's features: values in [0, 2)
        extra = 2 * rng.random((n, agent.n_extra)) * (rng.random((n, agent.n_extra)) < 0.6)
        extra = extra.astype(np.float32)
    elif agent.n_extra:
        extra = np.eye(agent.n_extra, dtype=np.float32)[rng.integers(0, agent.n_extra, n)]
    return obs, extra


def check(agent: QAgent, obs: np.ndarray, extra: np.ndarray | None, compiled: bool = False) -> int:
    """Every decided action is torch's and torch's values lie within the bound; returns
    how many were decided. ``compiled``: the greedy action of :mod:`dense_compiled`."""
    fast = NumpyQ(agent.q, compiled=compiled)
    want = agent.q_values(obs, extra)
    decided = 0
    for i in range(len(obs)):
        e = None if extra is None else extra[i : i + 1]
        q, bound = fast.forward(fast.inputs(obs[i : i + 1], e))
        assert np.all(np.abs(q.astype(np.float64) - want[i]) <= bound), i
        action = fast.greedy(obs[i : i + 1], e)
        if action is not None:
            assert action == int(want[i].argmax()), i
            decided += 1
    return decided


@pytest.mark.parametrize("model", ["paper_baseline__async", "paper_baseline__sync"])
def test_the_shipped_models_greedy_actions_are_torchs(model):
    agent = HDQNPolicy.load(MODELS / model).agent
    obs, extra = observations(agent, 3000, seed=1)
    assert check(agent, obs, extra) >= 0.95 * len(obs)  # near ties are rare


@pytest.mark.parametrize("compiled", [False, True])
@pytest.mark.parametrize(("shape", "actions", "extra"), [((1, 8, 7), 6, 4), ((2, 8, 12), 5, 0)])
def test_fresh_compact_networks_too(shape, actions, extra, compiled):
    torch.manual_seed(7)
    agent = QAgent(AgentConfig(network="compact"), shape, actions, extra)
    obs, ex = observations(agent, 1500, seed=2)
    assert check(agent, obs, ex, compiled) >= 0.9 * len(obs)


@pytest.mark.parametrize("compiled", [False, True])
def test_a_students_features_only_network(compiled):
    """The student's shape: no image (0 channels), about 180 features, 128 x 128 ReLUs; the
    compiled greedy action decides wherever numpy's does (and more often: a ReLU surely
    negative carries no error there), and the same."""
    torch.manual_seed(3)
    agent = QAgent(AgentConfig(network="student-wide"), (0, 1, 1), 5, 176)
    obs, extra = observations(agent, 1500, seed=4)
    assert check(agent, obs, extra, compiled) >= 0.9 * len(obs)
    plain, fast = NumpyQ(agent.q), NumpyQ(agent.q, compiled=True)
    for i in range(300):
        row = (obs[i : i + 1], extra[i : i + 1])  # type: ignore[index]
        expected, got = plain.greedy(*row), fast.greedy(*row)
        if expected is not None:
            assert got == expected
    assert fast.undecided <= plain.undecided  # both asked on every row


@pytest.mark.parametrize("compiled", [False, True])
def test_a_near_tie_is_left_to_torch(compiled):
    torch.manual_seed(0)
    agent = QAgent(AgentConfig(network="compact"), (1, 8, 7), 6, 4)
    with torch.no_grad():
        last = agent.q.head[-1]
        last.weight[1] = last.weight[0]  # actions 0 and 1 tie exactly
        last.bias[1] = last.bias[0]
        last.bias[[2, 3, 4, 5]] = -100.0
    obs, extra = observations(agent, 20, seed=3)
    fast = NumpyQ(agent.q, compiled=compiled)
    assert all(fast.greedy(obs[i : i + 1], extra[i : i + 1]) is None for i in range(20))
    assert fast.undecided == 20


@pytest.mark.parametrize("preset", ["paper", "pooled"])
def test_convolutional_networks_stay_on_torch(preset):
    agent = QAgent(AgentConfig(network=preset), (2, 8, 14), 5, 4)
    with pytest.raises(Unsupported):
        NumpyQ(agent.q)


def test_a_large_network_stays_on_torch():
    agent = QAgent(AgentConfig(network="compact"), (1, 8, 64), 1296, 0)  # the single mode's
    with pytest.raises(Unsupported, match="weights"):
        NumpyQ(agent.q)


@pytest.mark.parametrize(
    "model", ["paper_baseline__async", "paper_baseline__single", "paper_baseline__student"]
)
def test_a_runs_decisions_are_the_same_with_torch_alone(model):
    scenario = with_overrides(load_scenario("paper_baseline"), {"duration": 40.0, "warmup": 5.0})
    base = HDQNPolicy.load(MODELS / model)
    tables = []
    for numpy_forward in (True, False):
        policy = HDQNPolicy(base.agent, base.meta, numpy_forward=numpy_forward)
        result = simulate(scenario, policy, seed=4, engine="fast")
        tables.append((result.parts, result.decisions, result.kpis))
        if not numpy_forward or model.endswith("single"):
            assert policy.torch_decisions > 100  # every decision went through torch
        else:
            assert policy.torch_decisions < 0.05 * len(result.parts)  # numpy decided the rest
    pd.testing.assert_frame_equal(tables[0][0], tables[1][0])
    pd.testing.assert_frame_equal(tables[0][1], tables[1][1])
    assert tables[0][2] == tables[1][2]


def test_the_weights_are_copied_when_a_run_starts():
    """A policy built on a live training agent sees the weights of each run's start."""
    scenario = with_overrides(load_scenario("paper_baseline"), {"duration": 10.0, "warmup": 1.0})
    base = HDQNPolicy.load(MODELS / "paper_baseline__async")
    agent = QAgent(base.agent.config, base.agent.obs_shape, base.agent.n_actions, 4)
    agent.q.load_state_dict(base.agent.q.state_dict())
    policy = HDQNPolicy(agent, base.meta)
    simulate(scenario, policy, seed=1, engine="fast")
    first = policy._numpy
    with torch.no_grad():
        agent.q.head[-1].bias[0] += 1000.0  # training moved the weights: action 0 wins
    result = simulate(scenario, policy, seed=1, engine="fast")
    assert policy._numpy is not first
    rules = result.parts["rule"].dropna()
    assert len(rules) and (rules == base.meta["rules"][0]).all()
