"""Environment speed: env steps per second with a random policy, observation included.

Usage: ``python bench/bench_env.py [--scenario paper_baseline] [--steps 20000] [--profile]``

Measures the Gymnasium env (``PickPlaceEnv``, unwrapped and through ``gymnasium.make``) and
the PettingZoo AEC env (agent steps, each with ``last()`` and its observation), on one
core; then the Gymnasium env with a frame rendered every step (``rgb_array`` and ``ansi``,
on a tenth of the steps), and the cost of a copy (``copy.deepcopy``, which rebuilds the line
and replays the actions since the reset) after k steps. Random actions come from a seeded
numpy generator drawn up front, so the figure is the environment's cost, not the sampler's.
Two rates are printed: per wall-clock second and per CPU second of this process
(``time.process_time``); on a shared machine the second is the steadier measure of the
environment's own cost.
"""

from __future__ import annotations

import argparse
import copy
import cProfile
import pstats
import time
from collections.abc import Callable

import gymnasium as gym
import numpy as np

from pnp_twin.learning.envs import ENV_ID, PickPlaceAEC, PickPlaceEnv

Rates = tuple[float, float, int]  # steps per wall second, per CPU second, episodes ended


def bench_gym(env: gym.Env, steps: int, seed: int = 0, render: bool = False) -> Rates:
    """Steps per second of ``env`` under uniformly random actions; episodes reset as needed.
    With ``render``, ``env.render()`` after every step."""
    n = int(env.action_space.n)  # type: ignore[attr-defined]
    actions = np.random.default_rng(seed).integers(n, size=steps).tolist()
    env.reset(seed=seed)
    episodes = 0
    t0, c0 = time.perf_counter(), time.process_time()
    for a in actions:
        _obs, _r, term, trunc, _info = env.step(a)
        if render:
            env.render()
        if term or trunc:
            episodes += 1
            env.reset()
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    return steps / wall, steps / cpu, episodes


def bench_aec(env: PickPlaceAEC, steps: int, seed: int = 0) -> Rates:
    """Agent steps per second of the AEC env (``last()`` with its observation, then ``step``)."""
    k = len(env.rules)
    actions = np.random.default_rng(seed).integers(k, size=steps).tolist()
    env.reset(seed=seed)
    episodes = 0
    t0, c0 = time.perf_counter(), time.process_time()
    for a in actions:
        _obs, _r, term, trunc, _info = env.last()
        if term or trunc:
            episodes += 1
            env.reset()
            continue
        env.step(a)
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    return steps / wall, steps / cpu, episodes


def bench_copy(env: PickPlaceEnv, after: int, repeats: int = 5, seed: int = 0) -> float:
    """CPU milliseconds per ``copy.deepcopy(env)`` taken ``after`` steps into an episode."""
    n = int(env.action_space.n)  # type: ignore[attr-defined]
    rng = np.random.default_rng(seed)
    env.reset(seed=seed)
    for _ in range(after):
        env.step(int(rng.integers(n)))
    c0 = time.process_time()
    for _ in range(repeats):
        copy.deepcopy(env)
    return 1000.0 * (time.process_time() - c0) / repeats


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenario", default="paper_baseline")
    parser.add_argument("--steps", type=int, default=20_000)
    parser.add_argument("--channels", type=int, default=1)
    parser.add_argument("--profile", action="store_true", help="cProfile the gym env run")
    args = parser.parse_args()
    kw = {"scenario": args.scenario, "channels": args.channels}
    cases: list[tuple[str, Callable[[], Rates]]] = [
        ("gym PickPlaceEnv (unwrapped)", lambda: bench_gym(PickPlaceEnv(**kw), args.steps)),
        ("gym make(PickPlace-v0)", lambda: bench_gym(gym.make(ENV_ID, **kw), args.steps)),
        ("pettingzoo PickPlaceAEC", lambda: bench_aec(PickPlaceAEC(**kw), args.steps)),
    ]
    print(f"scenario {args.scenario}, {args.steps} steps, channels {args.channels}")
    for name, run in cases:
        wall, cpu, episodes = run()
        print(
            f"{name:30s} {wall:9,.0f} steps/s wall {cpu:9,.0f} steps/CPU-s "
            f"({episodes} episodes ended)"
        )
    frames = max(1, args.steps // 10)
    for mode in ("rgb_array", "ansi"):
        wall, cpu, _ = bench_gym(PickPlaceEnv(render_mode=mode, **kw), frames, render=True)
        name = f"gym + render {mode}"
        print(f"{name:30s} {wall:9,.0f} steps/s wall {cpu:9,.0f} steps/CPU-s ({frames} steps)")
    for after in (100, 1000, 4000):
        ms = bench_copy(PickPlaceEnv(**kw), after)
        print(f"deepcopy after {after:5d} steps      {ms:9.1f} ms CPU per copy")
    if args.profile:
        prof = cProfile.Profile()
        prof.runcall(bench_gym, PickPlaceEnv(**kw), args.steps)
        pstats.Stats(prof).sort_stats("tottime").print_stats(18)


if __name__ == "__main__":
    main()
