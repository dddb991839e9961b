"""Multi-agent quick start: IPPO with action masks on the compiled multi-agent vector env.

Four robots, one shared policy (TorchRL's MultiAgentMLP and masked categorical, ClipPPOLoss,
GAE discounted by simulated time), trained on the ``baseline`` task's training seeds, then
scored greedily on its evaluation seeds against the six rules and random rules (paired by
seed). Needs the ``marl`` extra (``pip install 'pnp-twin[marl]'``). About a minute or two
of CPU on one core; docs/semi_mdp.md gives the measured time and result.

    python examples/marl_ippo_quickstart.py                 # IPPO, 300,000 env steps
    python examples/marl_ippo_quickstart.py --algo mappo --steps 300000 --task slow_robot
"""

from __future__ import annotations

import argparse
import time

import numpy as np
import torch

from pnp_twin.learning.marl_eval import RULES, fixed_rule, random_rules, rates, summary
from pnp_twin.learning.marl_ppo import PPOConfig, train
from pnp_twin.learning.tasks import eval_seeds, get_task


def main() -> None:
    ap = argparse.ArgumentParser(description="IPPO/MAPPO quick start on the task suite")
    ap.add_argument("--task", default="baseline")
    ap.add_argument("--algo", default="ippo", choices=["ippo", "mappo"])
    ap.add_argument("--steps", type=int, default=300_000, help="env steps (all lines)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--eval-seeds", type=int, default=10)
    args = ap.parse_args()
    torch.set_num_threads(1)

    start, cpu = time.perf_counter(), time.process_time()
    cfg = PPOConfig(task=args.task, algo=args.algo, total_steps=args.steps, seed=args.seed)
    finished: list[float] = []  # G of the training episodes that ended

    def progress(row: dict[str, float]) -> None:
        if row["episodes"]:
            finished.append(row["train_G"])
        if row["iteration"] % 20 == 0:
            last = f"{finished[-1]:6.2f}" if finished else "     -"
            print(f"step {row['env_steps']:>9,.0f}  last training episodes' G {last}  "
                  f"entropy {row['entropy']:.3f}", flush=True)  # fmt: skip

    result = train(cfg, progress=progress)
    print(f"trained in {time.perf_counter() - start:.0f} s wall, "
          f"{time.process_time() - cpu:.0f} s CPU")  # fmt: skip

    task = get_task(args.task)
    seeds = eval_seeds(task, args.eval_seeds)
    learned = rates(task, result.policy.act, seeds)
    rand = rates(task, random_rules(0), seeds)
    rules = {r: rates(task, fixed_rule(r), seeds) for r in RULES}
    best = max(rules, key=lambda r: float(np.mean(rules[r])))
    s = summary(learned, {"random": rand, best: rules[best]})
    print(f"{args.algo} on {task.name}, seeds {seeds[0]}-{seeds[-1]}: G {s['gripping_rate']:.2f} % "
          f"[{s['ci_low']:.2f}, {s['ci_high']:.2f}]")  # fmt: skip
    for name in ("random", best):
        d = s[f"vs_{name}"]
        print(f"  vs {name:6s}: {d['diff']:+.2f} points [{d['ci_low']:+.2f}, {d['ci_high']:+.2f}]")
    print("  rules: " + ", ".join(f"{r} {np.mean(v):.2f}" for r, v in rules.items()))
    print(f"  random rules: {np.mean(rand):.2f}")


if __name__ == "__main__":
    main()
