"""VDN, QMIX or MAPPO from BenchMARL on a task of the suite (``pnp_twin.learning.benchmarl_task``).

    pip install --no-deps --target /tmp/bmlib benchmarl==1.5.2 torchrl==0.11.1 \
        tensordict==0.11.0 hydra-core==1.3.2 omegaconf antlr4-python3-runtime==4.9.3
    PYTHONPATH=/tmp/bmlib:. python examples/benchmarl_run.py vdn --frames 4096

BenchMARL 1.5.2 pins ``torchrl<0.12``; installed into its own folder as above it runs beside
the project's torch without replacing the project's TorchRL (docs/marl.md). Small settings:
batches of 2,048 frames from 16 lines of 60 s, 50 optimizer steps per batch (off-policy) or
4 minibatch passes (on-policy), an evaluation of 2 episodes every 4,096 frames; logs as CSV
under ``--out``.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from benchmarl.algorithms import MappoConfig, QmixConfig, VdnConfig
from benchmarl.experiment import Experiment, ExperimentConfig
from benchmarl.models.mlp import MlpConfig

from pnp_twin.learning.benchmarl_task import task

ALGOS = {"vdn": VdnConfig, "qmix": QmixConfig, "mappo": MappoConfig}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("algo", choices=sorted(ALGOS))
    ap.add_argument("--task", default="baseline")
    ap.add_argument("--frames", type=int, default=4096)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--out", type=Path, default=Path("/tmp/benchmarl_out"))
    a = ap.parse_args()
    cfg = ExperimentConfig.get_from_yaml()
    cfg.max_n_frames = a.frames
    cfg.on_policy_collected_frames_per_batch = cfg.off_policy_collected_frames_per_batch = 2048
    cfg.on_policy_n_envs_per_worker = cfg.off_policy_n_envs_per_worker = 16
    cfg.off_policy_n_optimizer_steps, cfg.off_policy_train_batch_size = 50, 256
    cfg.on_policy_n_minibatch_iters, cfg.on_policy_minibatch_size = 4, 512
    cfg.evaluation, cfg.evaluation_interval, cfg.evaluation_episodes = True, 4096, 2
    cfg.loggers, cfg.create_json, cfg.checkpoint_interval, cfg.render = ["csv"], False, 0, False
    cfg.sampling_device = cfg.train_device = cfg.buffer_device = "cpu"
    a.out.mkdir(parents=True, exist_ok=True)
    cfg.save_folder = str(a.out)
    line = task(a.task, overrides={"duration": 60.0, "warmup": 10.0}, max_steps=400)
    t0 = time.process_time()
    Experiment(task=line, algorithm_config=ALGOS[a.algo].get_from_yaml(),
               model_config=MlpConfig.get_from_yaml(), seed=a.seed, config=cfg).run()  # fmt: skip
    print(f"{a.algo} on {line.name}: {a.frames} frames, {time.process_time() - t0:.0f} s CPU")


if __name__ == "__main__":
    main()
