"""Train IPPO or MAPPO on a task, log it (CSV, TensorBoard) and save a ``marl:`` checkpoint.

    python bench/train_marl.py TASK --algo ippo --steps 200000 --out runs/ippo_baseline \
        [--seed 0] [--num-envs 32] [--unmasked] [--eval-every 20000] [--eval-seeds 4] \
        [--eval-duration 120] [--tensorboard]

Writes into ``--out``: ``progress.csv`` (a row per update; ``eval_G`` with its 95 %
interval at each ``--eval-every`` env steps, from ``--eval-seeds`` greedy runs of
``--eval-duration`` s on validation seeds), TensorBoard event files with ``--tensorboard``,
and the checkpoint (``model.safetensors``, ``meta.json``): then
``pnp-twin evaluate ... --policy marl:OUT`` or ``pnp-twin task score TASK --policy marl:OUT``.
See :mod:`pnp_twin.learning.marl_ppo`.
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

from pnp_twin.learning.marl_checkpoint import save_marl
from pnp_twin.learning.marl_log import TrainLog
from pnp_twin.learning.marl_ppo import ALGOS, PPOConfig, train
from pnp_twin.twin.errors import UserError


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    d = PPOConfig()
    ap.add_argument("task")
    ap.add_argument("--algo", choices=ALGOS, default=d.algo)
    ap.add_argument("--steps", type=int, default=d.total_steps)
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--seed", type=int, default=d.seed)
    ap.add_argument("--num-envs", type=int, default=d.num_envs)
    ap.add_argument("--unmasked", action="store_true")
    ap.add_argument("--duration", type=float, default=None, help="shorter training episodes, s")
    ap.add_argument("--eval-every", type=int, default=20_000)
    ap.add_argument("--eval-seeds", type=int, default=d.eval_seeds)
    ap.add_argument("--eval-duration", type=float, default=d.eval_duration)
    ap.add_argument("--tensorboard", action="store_true")
    a = ap.parse_args()
    cfg = PPOConfig(
        task=a.task, algo=a.algo, total_steps=a.steps, seed=a.seed, num_envs=a.num_envs,
        masked=not a.unmasked, duration=a.duration, eval_every=a.eval_every,
        eval_seeds=a.eval_seeds, eval_duration=a.eval_duration,
    )  # fmt: skip
    try:
        log = TrainLog(a.out, tensorboard=a.tensorboard)
        result = train(cfg, progress=log)
        log.close()
        save_marl(result, a.out)
    except UserError as e:
        print(f"error: {e}", file=sys.stderr)
        raise SystemExit(2) from None
    last = result.log[-1]
    g = last.get("eval_G", math.nan)
    print(f"{a.out}: {result.env_steps} env steps in {result.cpu_s:.0f} s CPU; last eval G {g:.2f}")


if __name__ == "__main__":
    main()
