"""``capacity --workers 2`` against ``--workers 1``: wall time side by side and the ratio.

One process pool serves the whole search (issue #32: a pool per flow made two workers five
times slower than one). Each run starts from an empty folder, so nothing is replayed; the
answers must be identical (seeds are fixed per run, whatever the worker count).

    PYTHONPATH=. python bench/capacity_workers.py [--replications 20] [--duration 120]
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

from pnp_twin.studies.capacity import run_capacity
from pnp_twin.twin.loader import load_scenario


def timed(workers: int, replications: int, duration: float) -> tuple[float, dict]:
    sc = load_scenario("paper_baseline", {"duration": duration, "warmup": duration / 6})
    with tempfile.TemporaryDirectory() as folder:
        t0 = time.perf_counter()
        result = run_capacity(sc, Path(folder), 95.0, 0.95, ["SD"], replications, workers)
        return time.perf_counter() - t0, result


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--replications", "-r", type=int, default=20)
    parser.add_argument("--duration", type=float, default=120.0)
    args = parser.parse_args()
    one, a = timed(1, args.replications, args.duration)
    two, b = timed(2, args.replications, args.duration)
    same = all(a[k] == b[k] for k in ("max_rate", "ci_low", "ci_high"))
    print(
        f"capacity paper_baseline -r {args.replications}, {args.duration:g} s runs, "
        f"{a.get('flows_evaluated', a['evaluated'])} flows"
    )
    print(f"  --workers 1: {one:6.2f} s")
    print(f"  --workers 2: {two:6.2f} s")
    print(f"  ratio 2/1:   {two / one:6.2f}   (same answer: {same})")


if __name__ == "__main__":
    main()
