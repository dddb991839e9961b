"""IPPO and MAPPO baselines on the task suite (TorchRL), scored on the tasks' evaluation seeds.

For each task: the six rules and random rules (every robot draws a rule uniformly at every
decision), then for each algorithm, variant (masked / unmasked) and training seed a
:func:`pnp_twin.learning.marl_ppo.train` run of ``--steps`` env steps, its greedy policy
scored on the task's evaluation seeds. Every G is measured on the multi-agent vector env at
the episode's end (:mod:`pnp_twin.learning.marl_eval`), so all rows of a task are paired by
seed. Results go to ``--out`` (JSON, rewritten after every run) and a markdown table.

    nice -n 10 python bench/marl_baselines.py --tasks baseline --algos ippo \
        --variants masked,unmasked --train-seeds 0,1,2 --steps 300000 --out marl.json
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path
from typing import Any

import numpy as np
import torch

from pnp_twin.learning.marl_eval import RULES, fixed_rule, random_rules, rates, summary
from pnp_twin.learning.marl_ppo import PPOConfig, train
from pnp_twin.learning.tasks import SUITE, eval_seeds, get_task


def _csv(text: str) -> list[str]:
    return [x.strip() for x in text.split(",") if x.strip()]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--tasks", default=",".join(t.name for t in SUITE))
    ap.add_argument("--algos", default="ippo,mappo")
    ap.add_argument("--variants", default="masked", help="masked, unmasked or both")
    ap.add_argument("--train-seeds", default="0", help="training seeds, comma-separated")
    ap.add_argument("--steps", type=int, default=300_000, help="env steps per training run")
    ap.add_argument("--num-envs", type=int, default=32)
    ap.add_argument("--eval-seeds", type=int, default=None, help="first N evaluation seeds")
    ap.add_argument("--out", type=Path, default=Path("marl_baselines.json"))
    args = ap.parse_args()
    torch.set_num_threads(1)
    out: dict[str, Any] = json.loads(args.out.read_text()) if args.out.is_file() else {}
    out.setdefault("settings", {}).update(
        {"steps": args.steps, "num_envs": args.num_envs, "eval": "greedy policy, 600 s runs"}
    )
    for name in _csv(args.tasks):
        task = get_task(name)
        seeds = eval_seeds(task, args.eval_seeds)
        row = out.setdefault(name, {"seeds": seeds, "runs": {}})
        t0 = time.process_time()
        rules = {r: rates(task, fixed_rule(r), seeds) for r in RULES}
        best = max(rules, key=lambda r: float(np.mean(rules[r])))
        rand = rates(task, random_rules(0), seeds)
        refs = {"random": rand, "best_rule": rules[best]}
        row["rules"] = {r: summary(v, {"random": rand}) for r, v in rules.items()}
        row["best_rule"] = best
        row["random"] = summary(rand, {"best_rule": rules[best]})
        row["reference_cpu_s"] = time.process_time() - t0
        print(f"{name}: best rule {best} {np.mean(rules[best]):.2f}, random {np.mean(rand):.2f}",
              flush=True)  # fmt: skip
        for algo in _csv(args.algos):
            for variant in _csv(args.variants):
                for seed in [int(s) for s in _csv(args.train_seeds)]:
                    cfg = PPOConfig(
                        task=name, algo=algo, masked=variant == "masked", seed=seed,
                        total_steps=args.steps, num_envs=args.num_envs,
                    )  # fmt: skip
                    res = train(cfg)
                    t1 = time.process_time()
                    values = rates(task, res.policy.act, seeds)
                    key = f"{algo}/{variant}/{seed}"
                    row["runs"][key] = {
                        **summary(values, refs),
                        "train": {k: v for k, v in res.to_json().items() if k != "log"},
                        "last_log": res.log[-1],
                        "eval_cpu_s": time.process_time() - t1,
                    }
                    s = row["runs"][key]
                    print(
                        f"  {key}: G {s['gripping_rate']:.2f} [{s['ci_low']:.2f}, "
                        f"{s['ci_high']:.2f}], vs random {s['vs_random']['diff']:+.2f} "
                        f"[{s['vs_random']['ci_low']:+.2f}, {s['vs_random']['ci_high']:+.2f}], "
                        f"vs {best} {s['vs_best_rule']['diff']:+.2f} "
                        f"[{s['vs_best_rule']['ci_low']:+.2f}, "
                        f"{s['vs_best_rule']['ci_high']:+.2f}]; train {res.wall_s:.0f} s wall, "
                        f"{res.cpu_s:.0f} s CPU",
                        flush=True,
                    )
                    args.out.write_text(json.dumps(out, indent=1))
        args.out.write_text(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
