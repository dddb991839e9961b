"""The task suite's multi-agent baselines over several training seeds, aggregated as
marl-eval does: IQM and mean with stratified bootstrap intervals over training runs.

    nice -n 10 python bench/marl_suite.py --algos ippo,mappo --train-seeds 0,1,2,3,4 \
        --steps 40000 --out docs/benchmark_runs/suite_v1.json [--tasks ...] [--save DIR]

For each task (its versioned id, e.g. ``slow_robot-v1``): the six rules on the task's
evaluation seeds (the best rule is the reference), then per algorithm and training seed a
:func:`pnp_twin.learning.marl_ppo.train` run of ``--steps`` env steps (masked, team reward,
the defaults otherwise), its greedy policy scored on the same seeds (paired). Each run's
score: its mean gain over the best rule (points), and that gain as a share of the planner
bound's gain over the best rule on the task (``--headroom DIR``: ``headroom_<task>.json`` of
``pnp-twin headroom --json``, the bound and the lookahead kept as reference lines). Then per
algorithm :func:`pnp_twin.learning.aggregate.aggregate` over tasks and runs. ``--save DIR``
keeps each run's checkpoint (``DIR/<task>/<algo>_<seed>``, a ``marl:`` policy). The JSON is
rewritten after every run (a rerun skips the runs it holds); ``--table`` prints markdown.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path
from typing import Any

import numpy as np
import torch

from pnp_twin.learning.aggregate import aggregate, normalized
from pnp_twin.learning.marl_eval import RULES, fixed_rule, rates
from pnp_twin.learning.marl_ppo import PPOConfig, train
from pnp_twin.learning.tasks import SUITE, eval_seeds, get_task

HEADROOM = Path(__file__).resolve().parents[1] / "docs" / "benchmark_runs"


def _csv(text: str) -> list[str]:
    return [x.strip() for x in text.split(",") if x.strip()]


def references(task_name: str, headroom: Path) -> dict[str, Any]:
    data = json.loads((headroom / f"headroom_{task_name}.json").read_text())
    return {k: {"policy": data[k]["policy"], "gain": data[k]["gain"],
                "gain_ci": [data[k]["gain_ci_low"], data[k]["gain_ci_high"]]}
            for k in ("lookahead", "bound")}  # fmt: skip


def table(out: dict[str, Any]) -> str:
    s = out["settings"]
    lines = [
        f"Suite {', '.join(out['per_task'])}; {s['steps']:,} env steps per run, training seeds "
        f"{s['train_seeds']}; gains in points over each task's best rule; normalized = share of "
        "the clairvoyant one-step bound's gain (0: best rule, 1: bound)",
        "",
        "| baseline | runs | IQM gain [95 % CI] | mean gain [95 % CI] | IQM normalized [95 % CI] |",
        "| --- | --- | --- | --- | --- |",
    ]
    for algo, agg in out["aggregate"].items():
        g, n = agg["gain"], agg["normalized"]
        lines.append(
            f"| {algo} | {g['runs']} | {g['iqm']:+.2f} [{g['iqm_ci'][0]:+.2f}, "
            f"{g['iqm_ci'][1]:+.2f}] | {g['mean']:+.2f} [{g['mean_ci'][0]:+.2f}, "
            f"{g['mean_ci'][1]:+.2f}] | {n['iqm']:+.2f} [{n['iqm_ci'][0]:+.2f}, "
            f"{n['iqm_ci'][1]:+.2f}] |"
        )
    refs = [out["per_task"][t]["references"] for t in out["per_task"]]
    for ref in ("lookahead", "bound"):
        gains = [r[ref]["gain"] for r in refs]
        shares = [r[ref]["gain"] / r["bound"]["gain"] for r in refs]
        lines.append(
            f"| {ref} (reference: the twin, seeds 1000-1019) | - | | mean over tasks "
            f"{np.mean(gains):+.2f} | mean over tasks {np.mean(shares):+.2f} |"
        )
    return "\n".join(lines)


def aggregates(out: dict[str, Any], algos: list[str]) -> dict[str, Any]:
    """Per algorithm, IQM and mean of the gain and the normalized gain over (task, run)."""
    got: dict[str, Any] = {}
    for algo in algos:
        by = {m: {t: [r[m] for k, r in out["per_task"][t]["runs"].items()
                      if k.startswith(f"{algo}/")] for t in out["per_task"]}
              for m in ("gain", "normalized")}  # fmt: skip
        if any(by["gain"].values()):
            got[algo] = {m: aggregate(v) for m, v in by.items()}
    return got


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--tasks", default=",".join(t.id for t in SUITE))
    ap.add_argument("--algos", default="ippo,mappo")
    ap.add_argument("--train-seeds", default="0,1,2,3,4")
    ap.add_argument("--steps", type=int, default=40_000)
    ap.add_argument("--num-envs", type=int, default=32)
    ap.add_argument("--headroom", type=Path, default=HEADROOM)
    ap.add_argument("--save", type=Path, default=None)
    ap.add_argument("--out", type=Path, default=Path("suite.json"))
    ap.add_argument("--table", action="store_true", help="print the table of --out and stop")
    args = ap.parse_args()
    out: dict[str, Any] = json.loads(args.out.read_text()) if args.out.is_file() else {}
    if args.table:  # from the runs held so far
        out["aggregate"] = aggregates(out, _csv(args.algos))
        print(table(out))
        return
    torch.set_num_threads(1)
    algos, seeds = _csv(args.algos), [int(s) for s in _csv(args.train_seeds)]
    tasks = [get_task(t) for t in _csv(args.tasks)]
    how = "greedy policy, the task's 20 evaluation seeds, 600 s runs"
    out["settings"] = {"steps": args.steps, "num_envs": args.num_envs, "train_seeds": seeds,
                       "eval": how}  # fmt: skip
    out["tasks"] = [t.id for t in tasks]
    per_task = out.setdefault("per_task", {})
    for task in tasks:
        row = per_task.setdefault(task.id, {"runs": {}})
        seeds_eval = eval_seeds(task)
        if "rules" not in row:
            rules = {r: rates(task, fixed_rule(r), seeds_eval) for r in RULES}
            best = max(rules, key=lambda r: float(np.mean(rules[r])))
            row.update(rules={r: float(np.mean(v)) for r, v in rules.items()}, best_rule=best,
                       best_per_seed=rules[best],
                       references=references(task.name, args.headroom))  # fmt: skip
        best = np.asarray(row["best_per_seed"])
        bound = row["references"]["bound"]["gain"]
        for algo in algos:
            for seed in seeds:
                key = f"{algo}/{seed}"
                if key in row["runs"]:
                    continue
                t0 = time.process_time()
                cfg = PPOConfig(task=task.id, algo=algo, seed=seed, total_steps=args.steps,
                                num_envs=args.num_envs)  # fmt: skip
                res = train(cfg)
                values = np.asarray(rates(task, res.policy.act, seeds_eval))
                gain = float((values - best).mean())
                if args.save is not None:
                    from pnp_twin.learning.marl_checkpoint import save_marl

                    save_marl(res, args.save / task.id / f"{algo}_{seed}")
                row["runs"][key] = {"G": float(values.mean()), "gain": gain,
                                    "normalized": normalized(gain, bound),
                                    "cpu_s": time.process_time() - t0}  # fmt: skip
                print(f"{task.id} {key}: G {values.mean():.2f}, gain {gain:+.2f}, "
                      f"{time.process_time() - t0:.0f} s CPU", flush=True)  # fmt: skip
                args.out.write_text(json.dumps(out, indent=1))
    out["aggregate"] = aggregates(out, algos)
    args.out.write_text(json.dumps(out, indent=1))
    print(table(out))


if __name__ == "__main__":
    main()
