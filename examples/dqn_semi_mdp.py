"""A CleanRL-style DQN on ``pnp_twin/PickPlace-v0`` with semi-MDP discounting, top to bottom.

Each step of the environment is a decision epoch lasting ``info["tau"]`` simulated seconds,
so the target discounts by ``gamma ** tau`` (``SemiMDPDiscount`` puts it in
``info["discount"]``) instead of a constant gamma. Everything else is CleanRL's ``dqn.py``:
an ``Args`` dataclass, one seeding block, a replay buffer, a target network, a linear
epsilon schedule. Run it from the repository root::

    python examples/dqn_semi_mdp.py --total-timesteps 50000
    python examples/dqn_semi_mdp.py --help

It prints one line per episode and, at the end, the greedy policy's gripping rate on the
line seed ``--eval-seed`` (the seed of ``pnp-twin run --seed``) next to every single rule's.
"""

from __future__ import annotations

import argparse
import random
import time
from dataclasses import dataclass, fields
from pathlib import Path

import gymnasium as gym
import numpy as np
import torch
from torch import nn

import pnp_twin.learning.envs  # noqa: F401  (registers pnp_twin/PickPlace-v0)
from pnp_twin.learning.smdp import SemiMDPDiscount


@dataclass
class Args:
    scenario: str = "two_robot"
    """shipped scenario name or file"""
    duration: float = 60.0
    """simulated feeding time of an episode, s"""
    seed: int = 1
    """seed of the run (torch, numpy, exploration, episode seeds)"""
    total_timesteps: int = 20_000
    """environment steps (decision epochs) to train for"""
    learning_rate: float = 5e-4
    """Adam learning rate"""
    buffer_size: int = 10_000
    """replay capacity"""
    gamma: float = 0.9
    """discount per simulated second"""
    target_network_frequency: int = 250
    """steps between target-network copies"""
    batch_size: int = 64
    """minibatch size"""
    start_e: float = 1.0
    """initial epsilon"""
    end_e: float = 0.05
    """final epsilon"""
    exploration_fraction: float = 0.5
    """fraction of the steps over which epsilon decays"""
    learning_starts: int = 1_000
    """steps before learning starts"""
    train_frequency: int = 4
    """steps between gradient steps"""
    eval_seed: int = 0
    """line seed of the final greedy evaluation (as `pnp-twin run --seed`)"""
    save: str = ""
    """if given, save the Q-network's state dict here (.pt)"""


def parse_args() -> Args:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    for f in fields(Args):
        kind = type(f.default)
        parser.add_argument("--" + f.name.replace("_", "-"), type=kind, default=f.default)
    return Args(**vars(parser.parse_args()))


class QNetwork(nn.Module):
    def __init__(self, env: gym.Env) -> None:
        super().__init__()
        n_in = int(np.prod(env.observation_space.shape))
        self.network = nn.Sequential(
            nn.Flatten(),
            nn.Linear(n_in, 120),
            nn.ReLU(),
            nn.Linear(120, 84),
            nn.ReLU(),
            nn.Linear(84, int(env.action_space.n)),
        )

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.network(x.float())


def linear_schedule(start_e: float, end_e: float, duration: int, t: int) -> float:
    slope = (end_e - start_e) / max(duration, 1)
    return max(slope * t + start_e, end_e)


def greedy_gripping_rate(q: QNetwork, env: gym.Env, line_seed: int) -> float:
    obs, _ = env.reset(options={"line_seed": line_seed})
    done = False
    while not done:
        with torch.no_grad():
            action = int(q(torch.as_tensor(obs[None])).argmax(dim=1)[0])
        obs, _r, term, trunc, info = env.step(action)
        done = term or trunc
    return float(info["gripping_rate"])


if __name__ == "__main__":
    args = parse_args()
    run_name = f"{Path(args.scenario).stem}__dqn_semi_mdp__{args.seed}"

    # seeding
    random.seed(args.seed)
    np.random.seed(args.seed)
    torch.manual_seed(args.seed)
    torch.set_num_threads(1)

    overrides = {"duration": args.duration, "warmup": min(5.0, args.duration / 5)}

    def make():
        return gym.make(
            "pnp_twin/PickPlace-v0",
            scenario=args.scenario,
            overrides=overrides,
        )

    env = SemiMDPDiscount(make(), gamma=args.gamma)
    env.action_space.seed(args.seed)

    q_network = QNetwork(env)
    optimizer = torch.optim.Adam(q_network.parameters(), lr=args.learning_rate)
    target_network = QNetwork(env)
    target_network.load_state_dict(q_network.state_dict())

    # replay buffer: the discount gamma**tau is stored per transition
    shape = env.observation_space.shape
    obs_buf = np.zeros((args.buffer_size, *shape), dtype=np.uint8)
    next_buf = np.zeros_like(obs_buf)
    act_buf = np.zeros(args.buffer_size, dtype=np.int64)
    rew_buf = np.zeros(args.buffer_size, dtype=np.float32)
    disc_buf = np.zeros(args.buffer_size, dtype=np.float32)
    term_buf = np.zeros(args.buffer_size, dtype=np.float32)
    size = 0

    start_time = time.time()
    obs, _ = env.reset(seed=args.seed)
    losses: list[float] = []
    for global_step in range(args.total_timesteps):
        epsilon = linear_schedule(
            args.start_e,
            args.end_e,
            int(args.exploration_fraction * args.total_timesteps),
            global_step,
        )
        if random.random() < epsilon:
            action = int(env.action_space.sample())
        else:
            with torch.no_grad():
                action = int(q_network(torch.as_tensor(obs[None])).argmax(dim=1)[0])
        next_obs, reward, terminated, truncated, info = env.step(action)

        i = global_step % args.buffer_size
        obs_buf[i], next_buf[i], act_buf[i] = obs, next_obs, action
        rew_buf[i], disc_buf[i], term_buf[i] = reward, info["discount"], float(terminated)
        size = min(size + 1, args.buffer_size)

        obs = next_obs
        if terminated or truncated:
            print(
                f"{run_name} step {global_step + 1}: episode G {info['gripping_rate']:.1f} %, "
                f"discounted return {info['discounted_return']:.2f}, "
                f"{(global_step + 1) / (time.time() - start_time):.0f} steps/s"
            )
            obs, _ = env.reset()

        if global_step > args.learning_starts and global_step % args.train_frequency == 0:
            idx = np.random.randint(0, size, args.batch_size)
            with torch.no_grad():
                target_max = target_network(torch.as_tensor(next_buf[idx])).max(dim=1).values
                # the semi-MDP target: r + gamma**tau * max_a' Q_target(s', a')
                td_target = torch.as_tensor(rew_buf[idx]) + torch.as_tensor(
                    disc_buf[idx]
                ) * target_max * (1 - torch.as_tensor(term_buf[idx]))
            q = q_network(torch.as_tensor(obs_buf[idx]))
            old_val = q.gather(1, torch.as_tensor(act_buf[idx])[:, None]).squeeze(1)
            loss = nn.functional.mse_loss(td_target, old_val)
            optimizer.zero_grad()
            loss.backward()
            optimizer.step()
            losses.append(loss.item())

        if global_step % args.target_network_frequency == 0:
            target_network.load_state_dict(q_network.state_dict())

    eval_env = make()
    g = greedy_gripping_rate(q_network, eval_env, args.eval_seed)
    rules = eval_env.unwrapped.rules
    singles = {}
    for k, rule in enumerate(rules):
        eval_env.reset(options={"line_seed": args.eval_seed})
        done = False
        while not done:
            _o, _r, term, trunc, info = eval_env.step(
                eval_env.unwrapped.encode([k] * eval_env.unwrapped.n_robots)
            )
            done = term or trunc
        singles[rule] = info["gripping_rate"]
    first, last = (
        np.mean(losses[:50]) if losses else float("nan"),
        np.mean(losses[-50:]) if losses else float("nan"),
    )
    print(
        f"{run_name}: greedy G {g:.2f} % on line seed {args.eval_seed}; "
        + ", ".join(f"{r} {v:.2f}" for r, v in singles.items())
        + f"; loss {first:.4g} -> {last:.4g}"
    )
    if args.save:
        torch.save(q_network.state_dict(), args.save)
