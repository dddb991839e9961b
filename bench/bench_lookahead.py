"""The lookahead controller's settings: gain over a rule and CPU per decision, per setting.

    python bench/bench_lookahead.py                      # the settings its defaults came from
    python bench/bench_lookahead.py lookahead:K=64,H=1.5 --seeds 100-105 --duration 300

For each policy name, the mean paired difference of the gripping rate to ``--reference``
(default SD) on ``--seeds`` (common random numbers; by default 100-105, seeds that the
evaluations, 0..N-1, do not use) with its 95 % t-interval, and the controller's CPU
milliseconds per decision (every decision counted, the ones with a single candidate too;
a busy machine inflates it).
"""

from __future__ import annotations

import argparse

import numpy as np

from pnp_twin.policies import make_policy
from pnp_twin.twin.loader import load_scenario
from pnp_twin.twin.run import simulate
from pnp_twin.twin.stats import t_interval

SETTINGS = [
    "lookahead:oracle=1,H=1.5",
    "lookahead:K=8,H=1.5",
    "lookahead:K=16,H=1.5",
    "lookahead:K=32,H=1.5",
    "lookahead:K=32,H=1",
    "lookahead:K=32,H=2.5",
    "lookahead:K=16,H=1",
]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("policies", nargs="*", default=SETTINGS)
    ap.add_argument("--scenario", default="paper_baseline")
    ap.add_argument("--seeds", default="100-105", help="FIRST-LAST")
    ap.add_argument("--duration", type=float, default=300.0)
    ap.add_argument("--warmup", type=float, default=30.0)
    ap.add_argument("--reference", default="SD")
    a = ap.parse_args()
    first, _, last = a.seeds.partition("-")
    seeds = list(range(int(first), int(last or first) + 1))
    sc = load_scenario(a.scenario, {"duration": a.duration, "warmup": a.warmup})
    ref = {
        s: simulate(sc, make_policy(a.reference), seed=s, engine="fast").kpis["gripping_rate"]
        for s in seeds
    }
    print(f"{a.scenario}, seeds {seeds[0]}-{seeds[-1]}, {a.duration:g} s runs, vs {a.reference}")
    for spec in a.policies:
        diffs, cpu = [], []
        for s in seeds:
            policy = make_policy(spec)
            g = simulate(sc, policy, seed=s, engine="fast").kpis["gripping_rate"]
            diffs.append(g - ref[s])
            stats = getattr(policy, "stats", None)
            if callable(stats):
                cpu.append(stats()["cpu_ms_per_decision"])
        mean, low, high = t_interval(diffs)
        ms = f"{np.mean(cpu):.2f} ms/decision" if cpu else ""
        print(f"{spec:32s} {mean:+.3f} [{low:+.3f}, {high:+.3f}]  {ms}", flush=True)


if __name__ == "__main__":
    main()
