"""Training speed of the HDQN: steps per second per mode, and time to beat the best rule.

Usage::

    python bench/bench_train.py [--steps 4000] [--modes single,sync,async] [--device cpu]
    python bench/bench_train.py --modes '' --run runs/paper_baseline__async__1
    python bench/bench_train.py --modes '' --rollout-episodes 10

Part 1 trains each mode for ``--steps`` transitions (learning from step 500, one gradient
step per 4 transitions, as the default run) and prints transitions per wall-clock second
and per CPU second of this process (the steadier figure on a shared machine). Part 2 reads
the ``eval.csv`` of a finished async run (``--run``) and prints the training wall time
until its greedy policy first beat the best single rule on the validation seeds by a margin
outside the paired 95 % confidence interval (a ``--targets rollout`` run's too). Part 3
labels ``--rollout-episodes`` episodes for rollout targets in this process on both engines,
side by side (the SimPy twin replaying each continuation from t = 0; the fast engine
forking at the decision), checks that the labels are identical and prints labelled
decisions per CPU second of each and their ratio.
"""

from __future__ import annotations

import argparse
import csv
import tempfile
import time
from pathlib import Path

import torch

from pnp_twin.learning.train import TrainArgs, train


def train_rate(mode: str, steps: int, device: str, scenario: str) -> tuple[float, float]:
    """(transitions per wall second, per CPU second) of a short training run of ``mode``."""
    with tempfile.TemporaryDirectory() as out:
        args = TrainArgs(
            scenario=scenario,
            mode=mode,
            out=out,
            steps=steps,
            device=device,
            learning_starts=500,
            eval_every=10**9,  # no evaluation inside the timing (one at the end)
            checkpoint_every=10**9,  # nor checkpoints (one at the end)
            eval_seeds=2,
            eval_duration=10.0,
        )
        t0, c0 = time.perf_counter(), time.process_time()
        train(args)
        return steps / (time.perf_counter() - t0), steps / (time.process_time() - c0)


def rollout_rates(episodes: int, scenario: str) -> tuple[dict[str, float], int, bool]:
    """(labelled decisions per CPU second per engine, labels, labels identical) of
    ``episodes`` rollout episodes labelled on each engine."""
    import numpy as np

    from pnp_twin.learning.rollout import LabelSettings, label_episode
    from pnp_twin.twin.loader import load_scenario

    line = load_scenario(scenario, {"termination": "t_continue", "warmup": 0.0})
    label_episode(line, 1, LabelSettings(futures=1), engine="fast")  # load the compiled code
    rates, out = {}, {}
    for engine in ("simpy", "fast"):
        c0 = time.process_time()
        out[engine] = [
            label_episode(line, 2_000_000 + e, LabelSettings(), engine=engine)
            for e in range(episodes)
        ]
        n = sum(len(x) for x in out[engine])
        rates[engine] = n / (time.process_time() - c0)
    same = all(
        np.array_equal(getattr(a, f), getattr(b, f))
        for a, b in zip(out["simpy"], out["fast"], strict=True)
        for f in ("obs", "robot", "advantage")
    )
    return rates, n, same


def first_beat(run: Path) -> dict[str, str] | None:
    """The first evaluation row of a run that beat the best single rule, if any."""
    with (run / "eval.csv").open() as f:
        for row in csv.DictReader(f):
            if row["beats_best_rule"] == "1":
                return row
    return None


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenario", default="paper_baseline")
    parser.add_argument("--steps", type=int, default=4000)
    parser.add_argument("--modes", default="single,sync,async")
    parser.add_argument("--device", default="cpu")
    parser.add_argument("--run", type=Path, default=None, help="a finished async run folder")
    parser.add_argument("--rollout-episodes", type=int, default=0)
    a = parser.parse_args()
    torch.set_num_threads(1)
    for mode in [m for m in a.modes.split(",") if m]:
        wall, cpu = train_rate(mode, a.steps, a.device, a.scenario)
        print(f"{mode:>6}: {wall:8.0f} steps/s wall, {cpu:8.0f} steps/s CPU ({a.device})")
    if a.rollout_episodes:
        rates, n, same = rollout_rates(a.rollout_episodes, a.scenario)
        print(
            f"rollout targets ({n} labels, identical: {same}): simpy {rates['simpy']:.1f}, "
            f"fast {rates['fast']:.1f} labelled decisions per CPU second: "
            f"{rates['fast'] / rates['simpy']:.1f}x"
        )
    if a.run is not None:
        row = first_beat(a.run)
        if row is None:
            print(f"{a.run.name}: never beat the best single rule in its evaluations")
        else:
            print(
                f"{a.run.name}: first beat {row['best_rule']} at step {row['step']} after "
                f"{float(row['wall_time']):.0f} s of training "
                f"(G {float(row['gripping_rate']):.2f} %, "
                f"{float(row['diff_vs_best_rule']):+.2f} +- {float(row['diff_ci']):.2f})"
            )


if __name__ == "__main__":
    main()
