"""The compiled engine's cost per event on the new line shapes against paper_baseline.

    python bench/bench_line_shapes.py [--hours 1] [--repeat 5]

For each line, one run of ``--hours`` simulated hours on the fast engine (``FastLine`` built
and run, the rule of the scenario), measured in turns with the baseline so a drift of the
machine's speed hits both alike; the best CPU time of ``--repeat`` turns over the events the
kernel processed (its event counter). Prints CPU us per event, the ratio to paper_baseline
and the issue's target (at most 1.2x for a two-sided line with three kinds).
"""

from __future__ import annotations

import argparse
import time

from pnp_twin.policies import make_policy
from pnp_twin.twin import load_scenario
from pnp_twin.twin.fast import layout as L
from pnp_twin.twin.fast.engine import FastLine
from pnp_twin.twin.scenario import Scenario

LINES = {
    "paper_baseline": "one side, one kind (the reference)",
    "baseline_two_sided_3_kinds": "paper_baseline, 2 and 4 facing, 3 kinds",
    "two_sided": "two sides facing, reach",
    "delta_over_belt": "over the belt, reach",
    "waste_sorting": "two sides, three kinds, kinds per robot",
}
TARGET = 1.2  # the bound for a two-sided, three-kind line
TWO_SIDED_3_KINDS = {  # paper_baseline's flow and robots, robots 2 and 4 facing 1 and 3
    "feeder.kinds": [
        {"name": "a", "share": 0.5, "value": 1.0},
        {"name": "b", "share": 0.3, "value": 2.0},
        {"name": "c", "share": 0.2, "value": 3.0},
    ],
    "robots.overrides": [{"robot": 2, "side": "lower"}, {"robot": 4, "side": "lower"}],
}


def scenario(name: str, duration: float) -> Scenario:
    """A line of LINES fed for ``duration`` s."""
    if name == "baseline_two_sided_3_kinds":
        return load_scenario("paper_baseline", {**TWO_SIDED_3_KINDS, "duration": duration})
    return load_scenario(name, {"duration": duration})


def one_run(sc: Scenario) -> tuple[float, int]:
    """CPU seconds and events of one fast run of ``sc`` with its own policy."""
    t0 = time.process_time()
    line = FastLine(sc, make_policy(sc.policy, sc.robots.count))
    line.run()
    return time.process_time() - t0, int(line.gs[L.SEQ])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--hours", type=float, default=1.0, help="simulated hours per run")
    parser.add_argument("--repeat", type=int, default=5, help="turns; the best counts")
    args = parser.parse_args()
    scenarios = {name: scenario(name, 3600.0 * args.hours) for name in LINES}
    for name in LINES:
        one_run(scenario(name, 80.0))  # compile and warm up
    best: dict[str, tuple[float, int]] = {}
    for _ in range(args.repeat):
        for name, sc in scenarios.items():
            took, events = one_run(sc)
            if name not in best or took < best[name][0]:
                best[name] = (took, events)
    base = best["paper_baseline"][0] / best["paper_baseline"][1]
    print(f"fast engine, {args.hours:g} simulated h per run, best of {args.repeat} turns")
    print(f"{'line':<27} {'shape':<40} {'events':>9} {'us/event':>9} {'ratio':>6}")
    for name, (took, events) in best.items():
        per = took / events
        print(f"{name:<27} {LINES[name]:<40} {events:>9} {1e6 * per:>9.3f} {per / base:>6.2f}")
    ratio = best["baseline_two_sided_3_kinds"][0] / best["baseline_two_sided_3_kinds"][1] / base
    verdict = "meets" if ratio <= TARGET else "misses"
    print(
        f"paper_baseline made two-sided with three kinds: {ratio:.2f}x its cost per event "
        f"(target <= {TARGET}x): {verdict}"
    )


if __name__ == "__main__":
    main()
