"""Tests a broken learner would fail: the weights move, the loss falls, the shipped trained
policy beats the best single rule (paired over seeds), and the shipped models' evaluation
rows reproduce exactly."""

from __future__ import annotations

import csv
import random
from pathlib import Path

import numpy as np
import pytest

torch = pytest.importorskip("torch")
pytest.importorskip("safetensors")

from pnp_twin.learning.dqn_update import DQNAgent  # noqa: E402
from pnp_twin.learning.train import TrainArgs, train  # noqa: E402
from pnp_twin.learning.train_checkpoint import load_trainer  # noqa: E402
from pnp_twin.policies.hdqn.agent import AgentConfig  # noqa: E402
from pnp_twin.policies.hdqn.checkpoint import load_agent  # noqa: E402
from pnp_twin.policies.hdqn.policy import HDQNPolicy  # noqa: E402
from pnp_twin.policies.registry import make_policy  # noqa: E402
from pnp_twin.policies.rules import RULES  # noqa: E402
from pnp_twin.twin.loader import load_scenario, with_overrides  # noqa: E402
from pnp_twin.twin.run import simulate  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
TINY = {"robots.count": 2, "feeder.rate": 5.0}


@pytest.fixture(scope="module")
def run(tmp_path_factory) -> Path:
    torch.set_num_threads(1)
    args = TrainArgs(
        scenario="paper_baseline",
        mode="async",
        out=str(tmp_path_factory.mktemp("learn")),
        steps=3000,
        episode_time=30.0,
        learning_starts=200,
        train_every=2,
        batch_size=32,
        buffer_size=3000,
        eval_every=3000,
        eval_seeds=2,
        eval_duration=15.0,
        log_every=100,
        target_every=100,
        device="cpu",
        overrides=dict(TINY),
    )
    return train(args)


def test_training_moves_every_weight(run):
    random.seed(1)
    torch.manual_seed(1)  # as train() seeds before building the agent
    initial = DQNAgent(
        AgentConfig("compact", 2.5e-4, 0.9, True, target_every=100), (1, 8, 7), 6, 2
    )  # the window of a 0.2192 m workspace: 7 of the belt image's 64 columns
    trained, _meta = load_agent(run)
    before, after = initial.q.state_dict(), trained.q.state_dict()
    assert before.keys() == after.keys()
    assert all(not torch.equal(before[k], after[k]) for k in before)


def test_the_td_loss_falls_on_the_runs_own_experience(run):
    """The learner fits its semi-MDP targets: on a minibatch of the run's replay, with the
    target network held, its updates lower the TD loss (a learner that does not step, steps
    the wrong way or regresses the wrong action would not)."""
    from dataclasses import replace

    from pnp_twin.learning.replay import ReplayBuffer

    with (run / "log.csv").open() as f:
        logged = [float(r["loss"]) for r in csv.DictReader(f) if r["loss"] != "nan"]
    assert len(logged) >= 20 and np.isfinite(logged).all()
    agent, _meta = load_trainer(run / "resume", train_state=True)
    agent.config = replace(agent.config, target_every=10**9)
    replay = ReplayBuffer(3000, (1, 8, 7), 2)
    replay.load(run / "resume" / "replay.npz")
    # a minibatch of the trainer's default size: in a batch of 256 the 7-column windows of
    # this 2-robot line alias states whose targets differ, and no fit halves that loss
    batch = replay.sample(64, np.random.default_rng(0))
    agent.q.train()
    losses = [agent.update(batch) for _ in range(200)]
    assert losses[-1] < 0.5 * losses[0]


def test_the_shipped_policy_beats_the_best_rule_paired():
    """The shipped model the README recommends (async, rollout labels) on the baseline line
    grips more than the best of the six rules, paired over 8 seeds (common random numbers):
    the 95 % CI of the difference lies above zero. Its 600 s evaluation says +0.41 points
    over SD on 20 seeds, 19 of them ahead; on these 120 s runs it is about +0.43 ± 0.10."""
    from scipy import stats

    scenario = with_overrides(load_scenario("paper_baseline"), {"duration": 120.0, "warmup": 20.0})
    policy = HDQNPolicy.load(ROOT / "models" / "paper_baseline__async_rollout")
    seeds = range(8)

    def grips(rule: str | None) -> np.ndarray:  # None: the trained policy
        chosen = policy if rule is None else make_policy(rule)
        return np.array([simulate(scenario, chosen, seed=s).kpis["gripping_rate"] for s in seeds])

    g = grips(None)
    rules = {r: grips(r) for r in RULES}
    best = max(rules, key=lambda r: float(rules[r].mean()))
    diff = g - rules[best]
    half = stats.t.ppf(0.975, len(diff) - 1) * diff.std(ddof=1) / np.sqrt(len(diff))
    assert diff.mean() - half > 0, (best, diff.mean(), half, g, rules[best])


def _first_rows(model: str) -> list[dict[str, str]]:
    with (ROOT / "models" / model / "evaluation.csv").open() as f:
        rows = list(csv.DictReader(f))
    want = {rows[0]["policy"], "SPT"}
    return [r for r in rows if r["seed"] == "0" and r["policy"] in want]


@pytest.mark.parametrize(
    "model",
    [
        "paper_baseline__async",
        "paper_baseline__async_rollout",
        "paper_baseline__single",
        "paper_baseline__sync",
    ],
)
def test_a_shipped_models_evaluation_rows_reproduce_exactly(model):
    rows = _first_rows(model)
    assert len(rows) == 2
    for row in rows:
        scenario = load_scenario(row["scenario"])
        duration = float(row["duration"])
        scenario = with_overrides(
            scenario,
            {
                "termination": row["termination"],
                "duration": duration,
                "warmup": min(scenario.warmup, duration / 5),
            },
        )
        policy = (
            HDQNPolicy.load(ROOT / "models" / model)
            if row["kind"] == "hdqn"
            else make_policy(row["policy"])
        )
        g = simulate(scenario, policy, seed=int(row["seed"])).kpis["gripping_rate"]
        assert g == pytest.approx(float(row["gripping_rate"]), abs=1e-9), row["policy"]
