"""IPPO with TorchRL's own parts on the twin's TorchRL env, reading top to bottom.

    python examples/torchrl_ippo.py --frames 200000 --num-envs 32

The env is :func:`pnp_twin.learning.envs.torchrl_env` (the compiled multi-agent vector env,
masks in its specs); the rest is TorchRL's multi-agent PPO recipe: a ``Collector``,
a shared-parameter ``MultiAgentMLP`` actor over a ``MaskedCategorical`` and a decentralised
critic (IPPO), ``ClipPPOLoss``, and GAE with the semi-MDP discount ``gamma ** tau`` per
step (a step lasts ``tau`` simulated seconds). Prints one line per batch: frames, the
reward per simulated second, the loss, and the mean G of the lines that ended.
"""

from __future__ import annotations

import argparse
from dataclasses import dataclass

import torch
from tensordict.nn import TensorDictModule
from torch import nn
from torchrl.collectors import Collector
from torchrl.modules import MaskedCategorical, MultiAgentMLP, ProbabilisticActor
from torchrl.objectives import ClipPPOLoss
from torchrl.objectives.value.functional import generalized_advantage_estimate

from pnp_twin.learning.envs import torchrl_env


@dataclass
class Args:
    task: str = "baseline"
    """A task of the suite (or a scenario name)."""
    frames: int = 200_000
    """Env steps, all lines together."""
    num_envs: int = 32
    steps_per_batch: int = 64
    """Env steps per line per batch."""
    duration: float | None = None
    """A shorter episode than the task's, s (None: the task's 600 s)."""
    epochs: int = 4
    minibatches: int = 4
    lr: float = 3e-4
    gamma: float = 0.9
    """Discount per simulated second."""
    lmbda: float = 0.95
    hidden: int = 64
    reward_scale: float = 0.05
    seed: int = 0


def main(args: Args) -> list[dict[str, float]]:
    torch.manual_seed(args.seed)
    torch.set_num_threads(1)
    short = {"duration": args.duration, "warmup": (args.duration or 0.0) / 5}
    extra = {} if args.duration is None else {"overrides": short}
    env = torchrl_env(args.task, num_envs=args.num_envs, team_reward=True, skip_noops=True,
                      **extra)  # fmt: skip
    env.set_seed(args.seed)
    n_agents, n_rules = env.n_agents, len(env.rules)
    obs_size = int(torch.tensor(env.observation_spec["agents", "observation"].shape[2:]).prod())

    def agents_mlp(outputs: int) -> nn.Module:
        return nn.Sequential(
            nn.Flatten(start_dim=-3),  # (C, H, w) window -> a vector per agent
            MultiAgentMLP(obs_size, outputs, n_agents, centralized=False, share_params=True,
                          depth=2, num_cells=args.hidden, activation_class=nn.Tanh),
        )  # fmt: skip

    actor = ProbabilisticActor(
        TensorDictModule(agents_mlp(n_rules), [("agents", "observation")], [("agents", "logits")]),
        in_keys={"logits": ("agents", "logits"), "mask": ("agents", "action_mask")},
        out_keys=[("agents", "action")],
        distribution_class=MaskedCategorical,
        return_log_prob=True,
        log_prob_key=("agents", "sample_log_prob"),
    )
    critic = TensorDictModule(
        agents_mlp(1), [("agents", "observation")], [("agents", "state_value")]
    )
    loss = ClipPPOLoss(actor, critic, clip_epsilon=0.2, entropy_coeff=0.01,
                       normalize_advantage=False)  # fmt: skip
    loss.set_keys(action=("agents", "action"), sample_log_prob=("agents", "sample_log_prob"),
                  value=("agents", "state_value"), reward=("agents", "reward"),
                  advantage=("agents", "advantage"),
                  value_target=("agents", "value_target"))  # fmt: skip
    optim = torch.optim.Adam(loss.parameters(), lr=args.lr)
    per_batch = args.num_envs * args.steps_per_batch
    collector = Collector(env, actor, frames_per_batch=per_batch,
                                  total_frames=max(per_batch, args.frames),
                          auto_register_policy_transforms=False)  # fmt: skip

    log = []
    for batch in collector:  # (lines, steps)
        with torch.no_grad():
            critic(batch)
            critic(batch["next"])
        nxt = batch["next"]
        shape = nxt["agents", "reward"].shape  # (lines, steps, agents, 1)
        done = nxt["terminated"][:, :, None].expand(shape)
        gamma = (args.gamma ** nxt["tau"])[:, :, None].expand(shape)
        adv, target = generalized_advantage_estimate(
            gamma, args.lmbda, batch["agents", "state_value"], nxt["agents", "state_value"],
            nxt["agents", "reward"] * args.reward_scale, done, done, time_dim=1,
        )  # fmt: skip
        batch["agents", "advantage"] = (adv - adv.mean()) / (adv.std() + 1e-8)
        batch["agents", "value_target"] = target
        flat = batch.reshape(-1)
        size = flat.shape[0] // args.minibatches
        for _ in range(args.epochs):
            order = torch.randperm(flat.shape[0])
            for b in range(args.minibatches):
                parts = loss(flat[order[b * size : (b + 1) * size]])
                total = parts["loss_objective"] + parts["loss_critic"] + parts["loss_entropy"]
                optim.zero_grad()
                total.backward()
                nn.utils.clip_grad_norm_(loss.parameters(), 1.0)
                optim.step()
        collector.update_policy_weights_()
        ended = nxt["done"].squeeze(-1)
        grips = nxt["gripping_rate"].squeeze(-1)[ended]
        row = {
            "frames": float(len(log) + 1) * per_batch,
            "reward_per_s": float(nxt["agents", "reward"].sum() / nxt["tau"].sum() / n_agents),
            "loss": float(total.detach()),
            "episodes": float(ended.sum()),
            "G": float(grips.mean()) if len(grips) else float("nan"),
        }
        log.append(row)
        print(", ".join(f"{k} {v:.4g}" for k, v in row.items()), flush=True)
    collector.shutdown()
    return log


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    for name, value in vars(Args()).items():
        kind = float if name == "duration" else type(value)
        ap.add_argument(f"--{name.replace('_', '-')}", type=kind, default=value)
    main(Args(**vars(ap.parse_args())))
