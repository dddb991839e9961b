"""Vector env speed: env steps per second of ``PickPlaceVectorEnv`` with random actions,
beside ``SyncVectorEnv`` of the SimPy ``PickPlaceEnv`` on the same settings, in one process.

Usage: ``python bench/bench_vector_env.py [--scenario paper_baseline] [--envs 64,256,1024]
[--threads 1,2] [--seconds 1] [--repeat 3] [--simpy-envs 8 --simpy-steps 300] [--profile]``
(``--threads``: the env's ``threads`` argument, each at most numba's thread count).

Each call draws one random action per env with numpy (``Discrete(625)`` on paper_baseline)
and steps every env; episodes end by the registered cap of 5000 steps or the scenario's
duration and autoreset inside ``step``. Rates are env steps per wall second (both threads
working: the figure to read) and per CPU second of the process, each the best of
``--repeat`` measurements (other work on a shared machine only ever slows a run down, and
a parallel step waits for its slowest thread). ``--profile`` splits a
step's wall time into the compiled call and the Python around it, and counts the kernel's
events per env step.
"""

from __future__ import annotations

import argparse
import time

import gymnasium as gym
import numba
import numpy as np

from pnp_twin.learning.envs import MAX_EPISODE_STEPS, PickPlaceEnv
from pnp_twin.learning.envs.vector_env import PickPlaceVectorEnv
from pnp_twin.twin.fast import layout as L

Rates = tuple[float, float]  # env steps per wall second, per CPU second


def bench(env: gym.vector.VectorEnv, calls: int, repeat: int = 1, seed: int = 0) -> Rates:
    """Env steps per second of ``env`` over ``calls`` steps with uniformly random actions
    (the best wall and the best CPU rate of ``repeat`` measurements)."""
    n = env.num_envs
    high = int(env.single_action_space.n)  # type: ignore[attr-defined]
    rng = np.random.default_rng(seed)
    env.reset(seed=seed)
    for _ in range(3):  # warm: the compiled code loaded, buffers touched
        env.step(rng.integers(high, size=n))
    best = (0.0, 0.0)
    for _ in range(repeat):
        t0, c0 = time.perf_counter(), time.process_time()
        for _ in range(calls):
            env.step(rng.integers(high, size=n))
        wall, cpu = time.perf_counter() - t0, time.process_time() - c0
        best = (max(best[0], n * calls / wall), max(best[1], n * calls / cpu))
    return best


def profile(env: PickPlaceVectorEnv, calls: int) -> None:
    """Where a step's time goes, and the kernel's events per env step."""
    n, b = env.num_envs, env.batch
    rng = np.random.default_rng(1)
    env.reset(seed=1)
    codes = env._decode(rng.integers(env.single_action_space.n, size=n))  # type: ignore[attr-defined]
    mode = np.ones(n, dtype=np.int8)
    seq0 = b.gs[:, L.SEQ].sum()
    t0 = time.perf_counter()
    for _ in range(calls):
        b.step(codes, mode)
    inner = time.perf_counter() - t0
    events = (b.gs[:, L.SEQ].sum() - seq0) / (n * calls)
    env.reset(seed=1)
    t0 = time.perf_counter()
    for _ in range(calls):
        env.step(rng.integers(env.single_action_space.n, size=n))  # type: ignore[attr-defined]
    outer = time.perf_counter() - t0
    print(
        f"  profile, {n} envs: {1e6 * outer / calls:.0f} us per call, of which the compiled "
        f"step {1e6 * inner / calls:.0f} us ({1e6 * inner / (n * calls):.2f} us per env "
        f"step, {events:.1f} kernel events each), Python around it "
        f"{1e6 * (outer - inner) / calls:.0f} us"
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenario", default="paper_baseline")
    ap.add_argument("--termination", default=None)
    ap.add_argument("--envs", default="64,256,1024")
    ap.add_argument("--threads", default="1,2")
    ap.add_argument("--seconds", type=float, default=1.0, help="about this long per figure")
    ap.add_argument("--repeat", type=int, default=3, help="best of this many measurements")
    ap.add_argument("--simpy-envs", type=int, default=8)
    ap.add_argument("--simpy-steps", type=int, default=300)
    ap.add_argument("--profile", action="store_true")
    args = ap.parse_args()
    kw = dict(
        scenario=args.scenario, termination=args.termination, max_episode_steps=MAX_EPISODE_STEPS
    )
    threads_max = numba.config.NUMBA_NUM_THREADS  # type: ignore[attr-defined]
    print(f"scenario {args.scenario}, numba {numba.__version__}, {threads_max} threads max")
    t0 = time.perf_counter()
    PickPlaceVectorEnv(num_envs=1, **kw).reset(seed=0)
    print(
        f"first vector env built and reset (compiled code loaded): {time.perf_counter() - t0:.1f}s"
    )
    simpy = gym.vector.SyncVectorEnv([lambda: PickPlaceEnv(**kw) for _ in range(args.simpy_envs)])
    s_wall, s_cpu = bench(simpy, args.simpy_steps, args.repeat)
    print(
        f"SimPy SyncVectorEnv x {args.simpy_envs}: {s_wall:,.0f} env steps/s wall, "
        f"{s_cpu:,.0f} per CPU s"
    )
    for n in [int(x) for x in args.envs.split(",")]:
        for threads in [int(x) for x in args.threads.split(",")]:
            env = PickPlaceVectorEnv(num_envs=n, threads=threads, **kw)
            calls = max(5, int(args.seconds * 5e5 / n))
            wall, cpu = bench(env, calls, args.repeat)
            print(
                f"vector env x {n:5d}, {threads} thread(s): {wall:>11,.0f} env steps/s wall, "
                f"{cpu:>11,.0f} per CPU s; {wall / s_wall:6.0f}x SimPy (wall)"
            )
        if args.profile:
            profile(PickPlaceVectorEnv(num_envs=n, **kw), max(5, int(args.seconds * 2e5 / n)))


if __name__ == "__main__":
    main()
