"""Speed of the twin: simulated hours per wall-clock second, decisions per second, and the
ratio to a bare SimPy loop running the same number of timeouts in the same process.

    python bench/bench_twin.py [--hours 1] [--repeat 5] [--policy SD]
"""

from __future__ import annotations

import argparse
import statistics
import time

import simpy

from policies import make_policy
from twin import load_scenario
from twin.line import Line


def bare_loop(n_events: int, n_procs: int) -> float:
    """Seconds for n_procs processes that together yield n_events timeouts."""

    def ticking(env: simpy.Environment, n: int):
        for _ in range(n):
            yield env.timeout(0.37)

    env = simpy.Environment()
    per = n_events // n_procs
    for _ in range(n_procs):
        env.process(ticking(env, per))
    t0 = time.perf_counter()
    env.run()
    return time.perf_counter() - t0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--scenario", default="paper_baseline")
    ap.add_argument("--policy", default="SD")
    ap.add_argument("--hours", type=float, default=1.0)
    ap.add_argument("--repeat", type=int, default=5)
    args = ap.parse_args()
    scenario = load_scenario(args.scenario, {"duration": 3600.0 * args.hours})
    walls, bares = [], []
    for r in range(args.repeat):
        line = Line(scenario, make_policy(args.policy), seed=r)
        t0 = time.perf_counter()
        line.run()
        walls.append(time.perf_counter() - t0)
        events = next(line.env._eid)  # events scheduled by the run (SimPy's own counter)
        decisions = sum(line.recorder.decisions.values())
        bares.append(bare_loop(events, scenario.robots.count))
    wall, bare = statistics.median(walls), statistics.median(bares)
    sim_hours = line.now / 3600.0
    print(
        f"scenario          {args.scenario} ({args.policy}, {scenario.robots.count} robots, "
        f"{scenario.feeder.rate:g} parts/s), {args.hours:g} h fed + drain, {args.repeat} runs"
    )
    print(f"wall per run      {wall:.3f} s (median; min {min(walls):.3f} s)")
    print(f"simulated h / s   {sim_hours / wall:.2f}")
    print(f"wall per sim hour {wall / sim_hours:.3f} s")
    print(f"events per run    {events}  ({events / wall:,.0f} events/s)")
    print(f"decisions / s     {decisions / wall:,.0f}  ({decisions} per run, NooPs included)")
    print(f"bare SimPy loop   {bare:.3f} s for the same {events} timeouts")
    print(
        f"ratio twin / bare {wall / bare:.2f}x (medians); {min(walls) / min(bares):.2f}x (minima, "
        "less sensitive to other load on the machine)"
    )


if __name__ == "__main__":
    main()
