"""IPPO / MAPPO with TorchRL on the multi-agent vector env: a tiny training run each, the
masked policy never takes a masked action, the mask changes its logits, the evaluator's
fixed rules and paired intervals. The full masked-vs-unmasked comparison is in
docs/benchmark.md with its command (minutes of CPU, not a test)."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import torch

from pnp_twin.learning.marl_eval import RULES, fixed_rule, random_rules, rates, summary
from pnp_twin.learning.marl_ppo import MarlError, PPOConfig, train
from pnp_twin.learning.tasks import make_env

TINY = dict(total_steps=256, num_envs=4, rollout=32, epochs=2, minibatches=2, duration=8.0)


@pytest.fixture(scope="module")
def masked_ippo():
    return train(PPOConfig(algo="ippo", masked=True, seed=3, **TINY))  # type: ignore[arg-type]


def _arrays(n: int = 8, steps: int = 40, seed: int = 0):
    """Observations and masks met on the line under random rules (some robots with no
    choice, some not deciding)."""
    env = make_env("baseline", "parallel_vector", num_envs=n, rules=RULES,
                   overrides={"duration": 8.0, "warmup": 1.0})  # fmt: skip
    obs, info = env.reset(seed=seed)
    act = random_rules(seed)
    out = []
    for _ in range(steps):
        out.append((obs.copy(), info["action_mask"].copy()))
        obs, _r, _te, _tr, info = env.step(act(obs, info["action_mask"]))
    return out


def test_masked_policy_never_takes_a_masked_action(masked_ippo):
    policy = masked_ippo.policy
    seen_forced = 0
    for obs, mask in _arrays():
        assert mask[:, :, 0].all()  # rule 0 is always allowed
        seen_forced += int((mask.sum(-1) == 1).sum())
        for greedy in (True, False):
            a = policy.act(obs, mask, greedy=greedy)
            assert a.shape == mask.shape[:2]
            assert np.take_along_axis(mask, a[..., None], -1).all()
        # the TorchRL actor itself (the one trained) samples only allowed actions
        from pnp_twin.learning.marl_ppo import _td

        td = _td(policy.features, obs, mask)
        with torch.no_grad():
            policy.actor(td)
        sampled = td["agents", "action"].numpy()
        assert np.take_along_axis(mask, sampled[..., None], -1).all()
        logp = td["agents", "action_log_prob"]
        forced = torch.from_numpy(mask.sum(-1) == 1)
        assert torch.allclose(logp[forced], torch.zeros(())), "a forced action has prob 1"
    assert seen_forced > 0  # the check met robots with only one allowed action


def test_mask_changes_the_logits(masked_ippo):
    policy = masked_ippo.policy
    obs, mask = next((o, m) for o, m in _arrays() if (m.sum(-1) > 1).any())
    full = np.ones_like(mask)
    only0 = np.zeros_like(mask)
    only0[..., 0] = 1
    assert not torch.allclose(policy.logits(obs, full), policy.logits(obs, only0))
    # the unmasked learner does not see the mask
    plain = train(PPOConfig(algo="ippo", masked=False, seed=3, **TINY))  # type: ignore[arg-type]
    assert torch.equal(plain.policy.logits(obs, full), plain.policy.logits(obs, only0))


def test_ippo_and_mappo_train_and_log(masked_ippo):
    mappo = train(PPOConfig(algo="mappo", masked=True, seed=3, **TINY))  # type: ignore[arg-type]
    for result in (masked_ippo, mappo):
        assert result.env_steps == 256 and len(result.log) == 2
        last = result.log[-1]
        for key in ("loss_objective", "loss_critic", "loss_entropy"):
            assert np.isfinite(last[key])
        assert result.sim_seconds > 0
    # MAPPO's critic reads the global state, IPPO's the agent's own observation
    assert mappo.critic.in_keys == [("agents", "state")]
    assert masked_ippo.critic.in_keys == [("agents", "observation")]
    # same seed, same run: training is repeatable
    again = train(PPOConfig(algo="ippo", masked=True, seed=3, **TINY))  # type: ignore[arg-type]
    assert again.log[-1]["loss_objective"] == masked_ippo.log[-1]["loss_objective"]


def test_bad_config_is_one_line():
    with pytest.raises(MarlError, match="algo"):
        train(PPOConfig(algo="qmix"))
    with pytest.raises(MarlError, match="total_steps"):
        train(PPOConfig(total_steps=0))


def test_evaluator_fixed_rules_and_paired_summary():
    seeds = [1000, 1001, 1002]
    sd = rates("baseline", fixed_rule("SD"), seeds, duration=20.0)
    # skipped epochs are forced NooPs: the same G with and without skip_noops
    assert sd == rates("baseline", fixed_rule("SD"), seeds, duration=20.0, skip_noops=False)
    lifo = rates("baseline", fixed_rule("LIFO"), seeds, duration=20.0)
    assert all(0.0 < g <= 100.0 for g in sd + lifo)
    s = summary(sd, {"lifo": lifo, "self": sd})
    assert s["vs_self"] == {"diff": 0.0, "ci_low": 0.0, "ci_high": 0.0}
    assert s["vs_lifo"]["diff"] == pytest.approx(np.mean(sd) - np.mean(lifo))
    assert s["ci_low"] <= s["gripping_rate"] <= s["ci_high"]


def test_the_quickstart_example_runs():
    root = Path(__file__).resolve().parents[2]
    out = subprocess.run(
        [sys.executable, "examples/marl_ippo_quickstart.py", "--steps", "4096",
         "--eval-seeds", "2"],
        cwd=root, capture_output=True, text=True, timeout=600,
    )  # fmt: skip
    assert out.returncode == 0, out.stderr[-2000:]
    text = out.stdout
    assert re.search(r"ippo on baseline, seeds 1000-1001: G [\d.]+ % \[", text), text
    assert re.search(r"vs random: [+-][\d.]+ points \[", text), text
    assert "rules: FIFO" in text and "random rules:" in text
