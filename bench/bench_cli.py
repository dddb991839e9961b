"""``pnp-twin run paper_baseline`` as a whole process: wall and CPU seconds, and its imports.

    python bench/bench_cli.py               # 7 runs, default engine (simpy)
    python bench/bench_cli.py --runs 11 --engine auto

Prints the median wall time and the median CPU time (user + system of the child; on a busy
machine the wall time measures the other load, the CPU time does not), the bare
interpreter's start-up for comparison, the time spent importing (``python -X importtime``,
the sum over top-level imports) and the slowest top-level imports. The target of issue #12
is under 0.6 s wall on a quiet machine.
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def timed(cmd: list[str]) -> tuple[float, float]:
    """Wall and CPU (user + system) seconds of one run of ``cmd``."""
    before = os.times()
    t0 = time.perf_counter()
    subprocess.run(cmd, cwd=ROOT, capture_output=True, check=True)
    wall = time.perf_counter() - t0
    after = os.times()
    cpu = (after.children_user - before.children_user) + (
        after.children_system - before.children_system
    )
    return wall, cpu


def medians(cmd: list[str], runs: int) -> tuple[float, float]:
    walls, cpus = zip(*(timed(cmd) for _ in range(runs)), strict=True)
    return statistics.median(walls), statistics.median(cpus)


def imports(cmd: list[str]) -> tuple[float, list[tuple[int, str]]]:
    """Seconds importing (top-level cumulative sum) and the top-level imports, slowest first."""
    out = subprocess.run(
        [sys.executable, "-X", "importtime", *cmd], cwd=ROOT, capture_output=True, text=True
    )
    rows = []
    for line in out.stderr.splitlines():
        parts = line.removeprefix("import time:").split("|")
        if len(parts) == 3 and parts[1].strip().isdigit():
            name = parts[2].rstrip()
            if not name.startswith("  "):  # top level: one space of indent
                rows.append((int(parts[1]), name.strip()))
    return sum(us for us, _ in rows) / 1e6, sorted(rows, reverse=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--runs", type=int, default=7, help="runs per measurement (median)")
    ap.add_argument("--engine", default="simpy", help="engine of the run (default simpy)")
    args = ap.parse_args()
    run = ["-m", "pnp_twin", "run", "paper_baseline", "--engine", args.engine]
    wall, cpu = medians([sys.executable, *run], args.runs)
    bare_wall, bare_cpu = medians([sys.executable, "-c", "pass"], args.runs)
    total, top = imports(run)
    print(f"cli   load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores")
    print(
        f"cli   pnp-twin run paper_baseline --engine {args.engine}: {wall:.3f} s wall, "
        f"{cpu:.3f} s CPU (median of {args.runs}; target < 0.6 s wall)"
    )
    print(f"cli   bare python -c pass: {bare_wall:.3f} s wall, {bare_cpu:.3f} s CPU")
    print(f"cli   importing: {total:.3f} s (python -X importtime, top-level sum)")
    print(
        "cli   slowest top-level imports (cumulative ms): "
        + ", ".join(f"{name} {us / 1000:.0f}" for us, name in top[:8])
    )


if __name__ == "__main__":
    main()
