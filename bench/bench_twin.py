"""Speed of the twin: simulated hours per wall-clock second, decisions per second, and the
ratio to a bare SimPy loop running the same number of timeouts in the same process.

    python bench/bench_twin.py [--hours 1] [--repeat 5] [--policy SD]
    python bench/bench_twin.py --compare /tmp/before   # against another checkout

``--compare TREE`` times the same runs in a checkout of another commit (made with
``git worktree add TREE REF``), alternating the two trees run by run, each in its own
interpreter, and prints both with their ratio. It reports CPU time of the process (less
sensitive than wall time to other load on the machine) and wall time.
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import time
from pathlib import Path

import simpy

from pnp_twin.policies import make_policy
from pnp_twin.twin import load_scenario
from pnp_twin.twin.line import Line

ROOT = Path(__file__).resolve().parents[1]

# One timed run, in whatever tree is first on PYTHONPATH (the same code for both sides).
TIMED_RUN = """
import json, sys, time
from pnp_twin.policies import make_policy
from pnp_twin.twin import load_scenario
from pnp_twin.twin.line import Line
scenario, policy, hours, seed = sys.argv[1], sys.argv[2], float(sys.argv[3]), int(sys.argv[4])
s = load_scenario(scenario, {"duration": 3600.0 * hours})
line = Line(s, make_policy(policy), seed=seed)
c0, w0 = time.process_time(), time.perf_counter()
line.run()
print(json.dumps({"cpu": time.process_time() - c0, "wall": time.perf_counter() - w0}))
"""


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


def timed_run(tree: Path, args: argparse.Namespace, seed: int) -> dict[str, float]:
    """CPU and wall seconds of one run in ``tree``'s own interpreter."""
    cmd = [sys.executable, "-c", TIMED_RUN, args.scenario, args.policy, str(args.hours), str(seed)]
    # run in the tree itself: ``python -c`` puts the working directory first on sys.path
    env = {"PYTHONPATH": str(tree)}
    out = subprocess.run(cmd, cwd=tree, env=env, capture_output=True, text=True, check=True)
    return json.loads(out.stdout)


def compare(args: argparse.Namespace) -> None:
    """Alternate runs of the other tree and this one; print the minima and their ratio."""
    other = Path(args.compare).resolve()
    times: dict[str, list[dict[str, float]]] = {"before": [], "after": []}
    for seed in range(args.repeat):
        times["before"].append(timed_run(other, args, seed))
        times["after"].append(timed_run(ROOT, args, seed))
    print(f"{args.scenario} ({args.policy}), {args.hours:g} h fed + drain, {args.repeat} runs each")
    for key in ("cpu", "wall"):
        b = [t[key] for t in times["before"]]
        a = [t[key] for t in times["after"]]
        print(
            f"{key:<5} before {min(b):.3f} s (median {statistics.median(b):.3f})  "
            f"after {min(a):.3f} s (median {statistics.median(a):.3f})  "
            f"ratio {min(a) / min(b):.2f}x (minima), "
            f"{statistics.median(a) / statistics.median(b):.2f}x (medians)"
        )
    print(f"before = {other}, after = {ROOT}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--scenario", default="paper_baseline")
    ap.add_argument("--policy", default="SD")
    ap.add_argument("--hours", type=float, default=1.0)
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--compare", metavar="TREE", help="another checkout to time against")
    args = ap.parse_args()
    if args.compare:
        compare(args)
        return
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
