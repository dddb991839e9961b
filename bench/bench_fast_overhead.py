"""The fast engine's cost beyond its event loop, its memory, and its cost per event by robots.

    python bench/bench_fast_overhead.py              # every figure, 9 interleaved turns
    python bench/bench_fast_overhead.py --repeat 15 --only overhead,memory,events

Prints each figure beside its target (issue 17), measured side by side in one process:

- ``overhead``: one simulated hour of paper_baseline (SD, seed 1). ``simulate(engine="fast")``
  as a whole (the line built and its parts drawn, the run, records and KPIs) against its
  bare event loop (the kernel's ``run_events`` from t = 0 to the end, on a line built
  beforehand), CPU seconds, the two measured in turns; medians of the turns and the median
  of the per-turn ratios. Target: ratio <= 1.3. Also the median of each step of
  ``simulate``, and the ratio without drawing the part stream (``twin.feeder``: the same
  numpy draws in both engines).
- ``memory``: the peak of memory allocated (``tracemalloc``: numpy arrays included) during
  ``simulate(engine="fast")`` of one simulated hour, per part fed, at 4 robots
  (paper_baseline) and at 64 (paper_baseline with 64 robots on a belt long enough for them,
  same feeder). Targets: <= 300 B per part at 4 robots, <= 1 kB at 64. The run's buffers
  pool (``twin.fast.pool``) is emptied first, so every array the run needs is counted.
- ``events``: CPU nanoseconds per event of the bare loop on those two lines (events: the
  robots' wake-ups processed), measured in turns; the ratio 64 : 4. Target: <= 1.3.
"""

from __future__ import annotations

import argparse
import gc
import statistics
import time
import tracemalloc
from collections.abc import Callable

from pnp_twin.policies import make_policy
from pnp_twin.twin import load_scenario, simulate
from pnp_twin.twin.fast import layout as L
from pnp_twin.twin.fast import pool
from pnp_twin.twin.fast.engine import FastLine
from pnp_twin.twin.feeder import Feeder
from pnp_twin.twin.plan import ARRIVALS, LATERAL, LinePlan
from pnp_twin.twin.scenario import Scenario

HOUR = 3600.0


def line_of(robots: int, duration: float = HOUR) -> Scenario:
    """paper_baseline with ``robots`` robots (the belt as long as their workspaces need)."""
    sets: dict[str, object] = {"duration": duration}
    if robots != 4:
        sets |= {"robots.count": robots, "belt.length": round(0.3 + robots * 0.2192 + 0.1, 4)}
    return load_scenario("paper_baseline", sets)


def cpu(fn: Callable[[], object]) -> float:
    gc.collect()
    t0 = time.process_time()
    fn()
    return time.process_time() - t0


def bare_loop(sc: Scenario, robots: int) -> tuple[float, int]:
    """CPU seconds of the kernel's event loop over a whole run, and the events it processed."""
    line = FastLine(sc, make_policy("SD", robots), seed=1)
    line.start(*line._rooms())
    t = cpu(lambda: line.advance(line.end_at))
    return t, int(line.gs[L.SEQ])


def _steps(sc: Scenario) -> dict[str, float]:
    """CPU seconds of each step of a fast simulate: the line built (its parts drawn), its
    state started, its events run (and open spans closed), its KPIs."""
    plan = LinePlan.of(sc, seed=1)
    seeds = plan.seeds()
    t = time.process_time()
    arrivals, lateral = plan.stream(seeds, ARRIVALS), plan.stream(seeds, LATERAL)
    Feeder(sc.feeder, sc.belt.width, arrivals, lateral, sc.source_dir).stream(sc.duration)
    t0 = time.process_time()
    line = FastLine(sc, make_policy("SD", 4), seed=1)
    t1 = time.process_time()
    line.start(*line._rooms())
    t2 = time.process_time()
    line.advance(line.end_at)
    line.finish()
    t3 = time.process_time()
    line.kpis(sc.warmup)
    t4 = time.process_time()
    return {
        "build (parts drawn included)": t1 - t0,
        "of which the part stream": t0 - t,
        "start": t2 - t1,
        "loop": t3 - t2,
        "kpis": t4 - t3,
    }


def overhead(repeat: int) -> None:
    sc = line_of(4)
    whole, loop, ratios = [], [], []
    steps: dict[str, list[float]] = {}
    for _ in range(repeat):
        a = cpu(lambda: simulate(sc, make_policy("SD", 4), seed=1, engine="fast"))
        b, _ = bare_loop(sc, 4)
        whole.append(a)
        loop.append(b)
        ratios.append(a / b)
        for name, t in _steps(sc).items():
            steps.setdefault(name, []).append(t)
    med = statistics.median
    print(
        f"overhead 1 h paper_baseline SD: simulate(engine='fast') {med(whole) * 1e3:7.2f} ms, "
        f"bare event loop {med(loop) * 1e3:7.2f} ms (CPU, medians of {repeat} turns): "
        f"ratio {med(ratios):.2f} (target <= 1.30)"
    )
    print(
        "overhead   steps (medians): "
        + ", ".join(f"{k} {med(v) * 1e3:.2f} ms" for k, v in steps.items())
    )
    parts = med(steps["of which the part stream"])
    print(
        f"overhead   without drawing the part stream (twin.feeder, shared with the SimPy "
        f"engine): ratio {(med(whole) - parts) / med(loop):.2f}"
    )


def memory() -> None:
    for robots, target in ((4, 300), (64, 1000)):
        sc = line_of(robots)
        simulate(sc, make_policy("SD", robots), seed=1, engine="fast")  # compiled, warmed
        pool.clear()  # the run allocates all its arrays, as a first run does: counted
        gc.collect()
        tracemalloc.start()
        r = simulate(sc, make_policy("SD", robots), seed=1, engine="fast")
        _, peak = tracemalloc.get_traced_memory()
        tracemalloc.stop()
        parts = r.kpis["parts_presented"]  # of the window; the run holds all parts fed
        fed = FastLine(sc, make_policy("SD", robots), seed=1).fed.size
        print(
            f"memory   1 h paper_baseline {robots:2d} robots: peak {peak / 2**20:6.1f} MiB for "
            f"{fed} parts fed ({parts} in the window): {peak / fed:5.0f} B per part "
            f"(target <= {target})"
        )


def events(repeat: int) -> None:
    lines = {robots: line_of(robots) for robots in (4, 64)}
    per: dict[int, list[float]] = {4: [], 64: []}
    ratios = []
    for _ in range(repeat):
        now = {}
        for robots, sc in lines.items():
            t, n = bare_loop(sc, robots)
            now[robots] = t / n * 1e9
            per[robots].append(now[robots])
        ratios.append(now[64] / now[4])
    med = statistics.median
    print(
        f"events   1 h paper_baseline bare loop: {med(per[4]):6.1f} ns per event at 4 robots, "
        f"{med(per[64]):6.1f} at 64 (CPU, medians of {repeat} turns): ratio "
        f"{med(ratios):.2f} (target <= 1.30)"
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--only", default="overhead,memory,events")
    ap.add_argument("--repeat", type=int, default=9)
    args = ap.parse_args()
    only = set(args.only.split(","))
    simulate(line_of(4, 120.0), make_policy("SD", 4), engine="fast")  # compile or load first
    if "overhead" in only:
        overhead(args.repeat)
    if "memory" in only:
        memory()
    if "events" in only:
        events(args.repeat)


if __name__ == "__main__":
    main()
