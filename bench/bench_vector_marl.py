"""Multi-agent vector env speed: agent steps per CPU second of ``PickPlaceParallelVectorEnv``.

Usage: ``python bench/bench_vector_marl.py [--scenario paper_baseline] [--envs 256,1024]
[--termination t_all,t_continue] [--seconds 2] [--repeat 3] [--skip-noops]``

One thread (``threads=1``), random rule indices for every agent each step, observations
(every agent's window) and infos (masks included) built each step, autoreset on. Printed per
setting, each the best of ``--repeat`` measurements: env steps per CPU second; agent steps
per CPU second (env steps x agents: every agent observes and passes an action each step, as
in PettingZoo's Parallel API) and decisions per CPU second (only the agents whose robot
decides: the actions that are used). One thread on one core: "per CPU second" is "per core".
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from pnp_twin.learning.envs.vector_marl import PickPlaceParallelVectorEnv


def bench(env: PickPlaceParallelVectorEnv, calls: int, repeat: int) -> tuple[float, float]:
    n, a, k = env.num_envs, env.n_agents, len(env.rules)
    rng = np.random.default_rng(0)
    env.reset(seed=0)
    actions = [rng.integers(k, size=(n, a)) for _ in range(calls)]
    best = (0.0, 0.0)
    for _ in range(repeat):
        decided = 0
        c0 = time.process_time()
        for x in actions:
            info = env.step(x)[4]
            decided += int(info["deciding"].sum())
        cpu = time.process_time() - c0
        best = (max(best[0], n * calls / cpu), max(best[1], decided / cpu))
    return best


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenario", default="paper_baseline")
    ap.add_argument("--envs", default="256,1024")
    ap.add_argument("--termination", default="t_all,t_continue")
    ap.add_argument("--seconds", type=float, default=2.0)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--skip-noops", action="store_true")
    args = ap.parse_args()
    t0 = time.process_time()
    PickPlaceParallelVectorEnv(1, args.scenario).reset(seed=0)
    print(f"first env built and reset: {time.process_time() - t0:.1f} s CPU", flush=True)
    for scheme in args.termination.split(","):
        for n in [int(x) for x in args.envs.split(",")]:
            env = PickPlaceParallelVectorEnv(
                n, args.scenario, termination=scheme, threads=1, skip_noops=args.skip_noops
            )
            calls = max(5, int(args.seconds * 2e5 / n))
            steps, decisions = bench(env, calls, args.repeat)
            print(
                f"{scheme:10s} x {n:5d} envs: {steps:>10,.0f} env steps, "
                f"{steps * env.n_agents:>10,.0f} agent steps, {decisions:>10,.0f} decisions "
                f"per CPU s (1 thread)",
                flush=True,
            )


if __name__ == "__main__":
    main()
