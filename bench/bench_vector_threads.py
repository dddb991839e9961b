"""Does a second numba thread help the compiled vector env on this machine, now?

Usage: ``python bench/bench_vector_threads.py [--envs 8,32,128,512] [--rounds 7]
[--steps 20000] [--scenario paper_baseline]``

For each number of envs, two ``PickPlaceVectorEnv`` (``threads=1`` and ``threads=2``) are
stepped with the same random actions in interleaved rounds (so that other work on a shared
machine weighs on both alike); each round steps each env about ``--steps`` env steps. It
prints the median env steps per wall second of each and their ratio (2 threads / 1), and the
steps per CPU second. A parallel step returns when its slowest thread is done: on a machine
whose cores are busy a second thread that gets no core makes the step wait, which is what the
default of one thread (:data:`pnp_twin.learning.vector.batch.DEFAULT_THREADS`) avoids.
"""

from __future__ import annotations

import argparse
import os
import statistics
import time

import numpy as np

from pnp_twin.learning.envs import MAX_EPISODE_STEPS
from pnp_twin.learning.envs.vector_env import PickPlaceVectorEnv


def run(env: PickPlaceVectorEnv, calls: int, rng: np.random.Generator) -> tuple[float, float]:
    n = env.num_envs
    high = int(env.single_action_space.n)  # type: ignore[attr-defined]
    actions = [rng.integers(high, size=n) for _ in range(calls)]
    t0, c0 = time.perf_counter(), time.process_time()
    for a in actions:
        env.step(a)
    return n * calls / (time.perf_counter() - t0), n * calls / (time.process_time() - c0)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenario", default="paper_baseline")
    ap.add_argument("--envs", default="8,32,128,512")
    ap.add_argument("--rounds", type=int, default=7)
    ap.add_argument("--steps", type=int, default=20_000)
    args = ap.parse_args()
    print(f"{os.cpu_count()} cores, load average {os.getloadavg()[0]:.1f}", flush=True)
    kw = dict(scenario=args.scenario, max_episode_steps=MAX_EPISODE_STEPS)
    for n in [int(x) for x in args.envs.split(",")]:
        envs = {t: PickPlaceVectorEnv(n, threads=t, **kw) for t in (1, 2)}
        for env in envs.values():
            env.reset(seed=0)
            env.step(np.zeros(n, dtype=np.int64))
        calls = max(3, args.steps // n)
        wall: dict[int, list[float]] = {1: [], 2: []}
        cpu: dict[int, list[float]] = {1: [], 2: []}
        for k in range(args.rounds):
            for t in (1, 2) if k % 2 == 0 else (2, 1):
                w, c = run(envs[t], calls, np.random.default_rng(k))
                wall[t].append(w)
                cpu[t].append(c)
        w1, w2 = statistics.median(wall[1]), statistics.median(wall[2])
        c1, c2 = statistics.median(cpu[1]), statistics.median(cpu[2])
        print(
            f"{n:5d} envs: 1 thread {w1:>10,.0f} steps/s wall ({c1:>10,.0f}/CPU s), "
            f"2 threads {w2:>10,.0f} ({c2:>10,.0f}/CPU s): 2/1 = {w2 / w1:.2f} wall; "
            f"load {os.getloadavg()[0]:.1f}",
            flush=True,
        )


if __name__ == "__main__":
    main()
