"""The semi-MDP helper and the CleanRL-style example that trains with it."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

from pnp_twin.learning.envs import ENV_ID
from pnp_twin.learning.smdp import SemiMDPDiscount, discount, semi_mdp_target

ROOT = Path(__file__).resolve().parents[2]


def test_discount_is_gamma_to_the_tau_and_the_target_uses_it():
    assert discount(0.9, 2.0) == pytest.approx(0.81)
    assert discount(0.5, np.array([0.0, 1.0, 3.0])).tolist() == [1.0, 0.5, 0.125]
    y = semi_mdp_target(
        np.array([1.0, 1.0]),
        np.array([2.0, 2.0]),
        np.array([0.0, 1.0]),
        np.array([10.0, 10.0]),
        0.5,
    )
    assert y.tolist() == [1.0 + 0.25 * 10.0, 1.0]
    with pytest.raises(ValueError, match="gamma"):
        discount(1.5, 1.0)


def test_wrapper_puts_the_discount_and_the_time_discounted_return_in_info():
    env = SemiMDPDiscount(gym.make(ENV_ID, overrides={"duration": 10.0, "warmup": 1.0}), 0.8)
    _obs, info = env.reset(seed=0)
    assert info["discount"] == 1.0 and info["discounted_return"] == 0.0
    t, ret = 0.0, 0.0
    for _ in range(40):
        _o, r, _te, _tr, info = env.step(0)
        ret += 0.8**t * float(r)
        t += info["tau"]
        assert info["discount"] == pytest.approx(0.8 ** info["tau"])
    assert info["discounted_return"] == pytest.approx(ret)
    assert info["time"] == pytest.approx(t)


def test_the_example_dqn_trains_and_its_loss_falls(tmp_path):
    weights = tmp_path / "q.pt"
    cmd = [
        sys.executable,
        "examples/dqn_semi_mdp.py",
        "--total-timesteps",
        "800",
        "--learning-starts",
        "100",
        "--duration",
        "20",
        "--save",
        str(weights),
    ]
    out = subprocess.run(
        cmd,
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=300,
        env={"PYTHONPATH": str(ROOT), "PATH": "/usr/bin:/bin"},
    )
    assert out.returncode == 0, out.stderr
    last = out.stdout.strip().splitlines()[-1]
    m = re.search(r"greedy G ([\d.]+) %.*loss ([\d.e+-]+) -> ([\d.e+-]+)", last)
    assert m, last
    g, first, final = (float(v) for v in m.groups())
    singles = [float(v) for v in re.findall(r"(?:FIFO|LIFO|SIRO|SD|LD) ([\d.]+)", last)]
    assert len(singles) == 5 and g >= min(singles)  # at least as good as the worst rule
    assert final < first  # the TD loss fell
    assert weights.is_file()
