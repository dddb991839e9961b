"""Benchmark: runs per second of the paper_27 study, serial vs a process pool vs Ray.

    python bench/bench_sweep.py [--points 27] [--replications 5] [--workers 2] [--no-ray]

Runs paper_27 (10 simulated minutes per run) into temporary folders: serial (--workers 1),
the local pool (--workers N) and the Ray backend (N CPUs), checks the three tables are
identical, and prints runs per second, the pool's speed-up and Ray's overhead over the pool.
``--points`` takes the first grid points only, for a shorter bench (it says what it ran).
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path

import pandas as pd

from pnp_twin.studies import Options, build_plan, run_sweep
from pnp_twin.studies.plan import StudyPlan
from pnp_twin.twin import load_scenario


def subset(plan: StudyPlan, points: int) -> StudyPlan:
    """The plan restricted to its first ``points`` grid points."""
    return StudyPlan(
        plan.scenario,
        plan.grid,
        plan.policies,
        plan.replications,
        plan.master_seed,
        plan.points[:points],
        plan.scenarios[:points],
    )


def timed(plan: StudyPlan, out: Path, options: Options) -> tuple[float, pd.DataFrame]:
    t0 = time.perf_counter()
    run_sweep(plan, out, options)
    wall = time.perf_counter() - t0
    return wall, pd.read_parquet(out / "results.parquet").drop(columns="wall_time")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--points", type=int, default=27)
    ap.add_argument("--replications", type=int, default=5)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--no-ray", action="store_true")
    args = ap.parse_args()
    plan = build_plan(load_scenario("paper_27"), replications=args.replications)
    plan = subset(plan, args.points)
    runs = len(plan.specs())
    print(
        f"paper_27: {len(plan.points)} of 27 points x {len(plan.policies)} policies "
        f"({', '.join(plan.policies)}) x {plan.replications} replications = {runs} runs of "
        f"{plan.scenario.duration:g} s simulated; {os.cpu_count()} CPUs, "
        f"load {os.getloadavg()[0]:.2f}"
    )
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        serial, t1 = timed(plan, root / "serial", Options(workers=1))
        print(f"serial      : {serial:7.2f} s  {runs / serial:6.2f} runs/s")
        pool, t2 = timed(plan, root / "pool", Options(workers=args.workers))
        print(
            f"{args.workers} workers   : {pool:7.2f} s  {runs / pool:6.2f} runs/s  "
            f"speed-up {serial / pool:.2f}x"
        )
        pd.testing.assert_frame_equal(t1, t2)
        if not args.no_ray:
            ray, t3 = timed(plan, root / "ray", Options(backend="ray", workers=args.workers))
            print(
                f"ray ({args.workers} cpus): {ray:7.2f} s  {runs / ray:6.2f} runs/s  "
                f"overhead vs pool {ray - pool:+.2f} s ({ray / pool:.2f}x), incl. Ray start"
            )
            pd.testing.assert_frame_equal(t1, t3)
        print("tables identical across backends: yes")


if __name__ == "__main__":
    main()
