"""Benchmark: a study's whole CPU against its simulations' CPU (target: within 1.3x).

    python bench/bench_study_overhead.py [--scenario paper_27] [--rounds 3] [--report]

One process, one worker, no report: ``run_sweep`` of the scenario's whole study (paper_27:
27 points x 4 policies x 5 replications = 540 runs) into a fresh temporary folder, and the
same runs' simulations alone (``simulate_spec`` of every run spec: the engine and its KPIs,
no journal, rows, tables or files), interleaved round by round so the machine's load hits
both alike. Prints each round's CPU seconds (``time.process_time``) and ratio, the median
ratio and the target beside it. The compiled kernel is loaded before the first round.
``--report`` also times building the HTML report of the last study folder, apart.
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time
from pathlib import Path

from pnp_twin.studies import Options, build_plan, run_sweep
from pnp_twin.studies.execute import simulate_spec
from pnp_twin.twin import load_scenario
from pnp_twin.twin.fast import prepare

TARGET = 1.3


def cpu(fn) -> float:  # type: ignore[no-untyped-def]
    t0 = time.process_time()
    fn()
    return time.process_time() - t0


def simulations(specs: list) -> None:  # type: ignore[type-arg]
    for spec in specs:
        simulate_spec(spec)  # dropped at once, as the study drops each run's result


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenario", default="paper_27")
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--report", action="store_true", help="also time the HTML report")
    args = ap.parse_args()
    plan = build_plan(load_scenario(args.scenario))
    specs = plan.specs()
    prepare()  # the compiled kernel, loaded (or compiled) before anything is timed
    print(
        f"{args.scenario}: {len(specs)} runs of {plan.scenario.duration:g} s simulated, "
        "one worker, no report"
    )
    ratios = []
    with tempfile.TemporaryDirectory() as tmp:
        last = Path(tmp)
        for k in range(args.rounds):
            sims = cpu(lambda: simulations(specs))
            last = Path(tmp) / f"study{k}"
            study = cpu(lambda: run_sweep(plan, last, Options(workers=1)))  # noqa: B023
            ratios.append(study / sims)
            print(
                f"round {k + 1}: study {study:6.2f} s CPU, simulations {sims:6.2f} s CPU, "
                f"ratio {study / sims:.2f}"
            )
        med = statistics.median(ratios)
        verdict = "meets" if med <= TARGET else "misses"
        print(f"study / simulations: median {med:.2f} (target <= {TARGET}: {verdict})")
        if args.report:
            from pnp_twin.reports import build_report

            print(f"report building, apart: {cpu(lambda: build_report(last)):.2f} s CPU")


if __name__ == "__main__":
    main()
