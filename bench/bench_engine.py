"""The fast engine against the SimPy twin, measured side by side in one process.

    python bench/bench_engine.py                 # everything, paper_27 shortened (--quick)
    python bench/bench_engine.py --full-study    # paper_27 as shipped: 540 runs of 600 s
    python bench/bench_engine.py --only line,policy,compile,study,cli

Prints, for each measurement, both engines and their ratio:

- ``line``: one simulated hour of paper_baseline (SD and SPT), CPU seconds of the engine
  alone (``Line`` built and run, against ``FastLine`` built and run) and of the whole
  ``simulate()`` (records, tables and KPIs included): the best of ``--repeat`` turns, each
  one SimPy call and five fast ones.
- ``policy``: ten simulated minutes of paper_baseline with a Python policy, the shipped
  rollout-trained HDQN (``models/paper_baseline__async_rollout``), through ``simulate()``
  on both engines (the fast one calls it back at each decision); CPU seconds, best of
  ``--repeat``, and whether the KPIs are identical.
- ``compile``: the first call in a fresh process with an empty numba cache (compiling),
  then in another fresh process with that cache (loading); wall seconds.
- ``study``: paper_27 with the same workers on both engines, runs per wall second, and
  whether the study tables are identical (engine and wall-time columns aside).
- ``cli``: ``pnp-twin run paper_baseline`` as a whole process, wall seconds (best of 3),
  and the slowest imports (``python -X importtime``).
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import pandas as pd

from pnp_twin.policies import make_policy
from pnp_twin.studies import Options, build_plan, run_sweep
from pnp_twin.twin import load_scenario, simulate
from pnp_twin.twin.fast.engine import FastLine
from pnp_twin.twin.line import Line
from pnp_twin.twin.scenario import Scenario

ROOT = Path(__file__).resolve().parents[1]
TABLES = ("results.csv", "summary.csv", "paired.csv", "best.csv")


def cpu(fn, repeat: int) -> float:  # noqa: ANN001
    """Best CPU seconds of ``repeat`` calls of ``fn``."""
    best = float("inf")
    for _ in range(repeat):
        t0 = time.process_time()
        fn()
        best = min(best, time.process_time() - t0)
    return best


def interleaved(slow, fast, repeat: int) -> tuple[float, float]:  # noqa: ANN001
    """Best CPU seconds of each, measured in turns (one slow call, then five fast ones, as
    often as ``repeat``) so that a drift of the machine's speed hits both alike."""
    a = b = float("inf")
    for _ in range(repeat):
        a = min(a, cpu(slow, 1))
        b = min(b, cpu(fast, 5))
    return a, b


def line_bench(repeat: int) -> None:
    sc = load_scenario("paper_baseline", {"duration": 3600.0})
    for rule in ("SD", "SPT"):
        line_rule(sc, rule, repeat)


def line_rule(sc: Scenario, rule: str, repeat: int) -> None:
    def simpy_line() -> None:
        Line(sc, make_policy(rule, 4), seed=1).run()

    def fast_line() -> None:
        FastLine(sc, make_policy(rule, 4), seed=1).run()

    fast_line()  # compile or load the kernel first
    a, b = interleaved(simpy_line, fast_line, repeat)
    print(
        f"line  1 h paper_baseline {rule:3s} engine   simpy {a:8.4f} s  fast {b:8.4f} s"
        f"  ratio {a / b:6.1f}x"
    )
    a, b = interleaved(
        lambda: simulate(sc, make_policy(rule, 4), seed=1, engine="simpy"),
        lambda: simulate(sc, make_policy(rule, 4), seed=1, engine="fast"),
        repeat,
    )
    print(
        f"line  1 h paper_baseline {rule:3s} simulate simpy {a:8.4f} s  fast {b:8.4f} s"
        f"  ratio {a / b:6.1f}x"
    )


def policy_bench(repeat: int) -> None:
    sc = load_scenario("paper_baseline", {"duration": 600.0})
    spec = f"hdqn:{ROOT / 'models' / 'paper_baseline__async_rollout'}"
    kpis = {}

    def run(engine: str) -> None:
        kpis[engine] = simulate(sc, make_policy(spec, 4), seed=1, engine=engine).kpis

    run("fast")  # load the kernel and torch first
    a, b = cpu(lambda: run("simpy"), repeat), cpu(lambda: run("fast"), repeat)
    print(
        f"policy 600 s paper_baseline HDQN simulate simpy {a:8.4f} s  fast {b:8.4f} s"
        f"  ratio {a / b:6.1f}x  KPIs identical: {repr(kpis['simpy']) == repr(kpis['fast'])}"
    )


def compile_bench() -> None:
    code = (
        "import time; t=time.perf_counter(); c=time.process_time();"
        "from pnp_twin.twin import load_scenario, simulate;"
        "from pnp_twin.policies import make_policy;"
        "sc=load_scenario('two_robot', {'duration': 5.0, 'warmup': 1.0});"
        "simulate(sc, make_policy('SPT', 2), engine='fast');"
        "print(time.perf_counter()-t, time.process_time()-c)"
    )
    with tempfile.TemporaryDirectory() as cache:
        env = {**os.environ, "NUMBA_CACHE_DIR": cache}
        runs = []
        for _ in range(2):
            out = subprocess.run(
                [sys.executable, "-c", code], env=env, cwd=ROOT, capture_output=True, text=True,
                check=True,
            )  # fmt: skip
            runs.append([float(x) for x in out.stdout.split()])
    (w0, c0), (w1, c1) = runs
    print(
        f"compile first fast run in a fresh process (imports included): empty numba cache "
        f"{w0:.2f} s wall / {c0:.2f} s CPU; cached {w1:.2f} s wall / {c1:.2f} s CPU"
    )


def study_bench(full: bool, workers: int) -> None:
    sets = {} if full else {"sweep.replications": 2, "sweep.duration": 120.0, "sweep.warmup": 20.0}
    sc = load_scenario("paper_27", sets)
    plan = build_plan(sc)
    n = len(plan.specs())
    rates = {}
    with tempfile.TemporaryDirectory() as tmp:
        for engine in ("simpy", "fast"):
            opts = Options(workers=workers)
            opts.engine = engine
            t0 = time.perf_counter()
            run_sweep(plan, Path(tmp) / engine, opts)
            rates[engine] = n / (time.perf_counter() - t0)
        same = all(
            _table(Path(tmp) / "simpy" / t).equals(_table(Path(tmp) / "fast" / t)) for t in TABLES
        )
    label = "paper_27" if full else "paper_27 (2 reps x 120 s)"
    print(
        f"study {label}: {n} runs, {workers} workers: simpy {rates['simpy']:.1f} runs/s, "
        f"fast {rates['fast']:.1f} runs/s, ratio {rates['fast'] / rates['simpy']:.1f}x, "
        f"tables identical: {same}"
    )


def _table(path: Path) -> pd.DataFrame:
    df = pd.read_csv(path)
    return df.drop(columns=[c for c in ("wall_time", "engine") if c in df])


def cli_bench() -> None:
    exe = Path(sys.executable).with_name("pnp-twin")
    for engine in ("simpy", "fast"):
        walls = []
        for _ in range(3):
            t0 = time.perf_counter()
            subprocess.run(
                [str(exe), "run", "paper_baseline", "--engine", engine],
                cwd=ROOT,
                capture_output=True,
                check=True,
            )
            walls.append(time.perf_counter() - t0)
        print(
            f"cli   pnp-twin run paper_baseline --engine {engine}: {min(walls):.2f} s wall "
            "(best of 3)"
        )
    out = subprocess.run(
        [sys.executable, "-X", "importtime", "-m", "pnp_twin", "run", "paper_baseline"],
        cwd=ROOT,
        capture_output=True,
        text=True,
    )
    rows = []
    for line in out.stderr.splitlines():
        parts = line.removeprefix("import time:").split("|")
        if len(parts) == 3 and parts[1].strip().isdigit():
            name = parts[2].rstrip()
            if not name.startswith("  "):  # top level: one space of indent
                rows.append((int(parts[1]), name.strip()))
    top = sorted(rows, reverse=True)[:6]
    print(
        "cli   slowest top-level imports (cumulative ms): "
        + ", ".join(f"{name} {us / 1000:.0f}" for us, name in top)
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--only", default="line,policy,compile,study,cli")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--full-study", action="store_true", help="paper_27 as shipped (long)")
    args = ap.parse_args()
    only = set(args.only.split(","))
    if "line" in only:
        line_bench(args.repeat)
    if "policy" in only:
        policy_bench(args.repeat)
    if "compile" in only:
        compile_bench()
    if "study" in only:
        study_bench(args.full_study, args.workers)
    if "cli" in only:
        cli_bench()


if __name__ == "__main__":
    main()
