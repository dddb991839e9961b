"""How much of the lookahead controller's gain does a student keep, at what CPU per decision?

    python bench/student_share.py SCENARIO [--set path=value ...] --policy hdqn:NAME [...]
        [--seeds 20] [--lookahead lookahead:K=16,H=1,base=auto] [--workers 2]
        [--first-seed S] [--cache DIR] [--json]

On one line and the held-out seeds 0..N-1 (``--first-seed S``: S..S+N-1; 600 s runs as the
scenario says, the compiled engine, common random numbers), as ``pnp-twin headroom``
measures them: every rule, the best rule (the best mean on these seeds), the lookahead
controller and each ``--policy``, with the paired gain over the best rule and its 95 %
t-interval. For each policy the **share of the lookahead's gain**,
``mean(G_policy - G_best) / mean(G_lookahead - G_best)`` over the seeds, with a 95 % interval
from the paired bootstrap over seeds (10,000 resamples of the seeds, the ratio recomputed on
each; percentile interval), and the CPU per decision: the
``process_time`` spent in the policy's ``choose`` (observation, features, network, rule)
divided by its decisions; the lookahead's is its own ``policy_stats``. The CPU ratio is the
policy's CPU per decision over the lookahead's, measured in the same process pool.

CPU per decision is measured apart from the seeds' runs, so that the lookahead and the
policies run under the same load: ``--cpu-rounds`` rounds (default 3) of one ``--cpu-duration``
s run (default 120) of the lookahead and then of each policy, back to back in this process,
on seed 100 + round; each one's CPU per decision is its total CPU over its decisions. One
uncounted run of each first (seed 99) loads their compiled code, as a controller that runs
for hours has it loaded.

``--cache DIR`` keeps each (line, policy, seed) result in a JSON file there, so a second
student on the same line does not rerun the lookahead (the runs are deterministic).

    python bench/student_share.py --table FILE.json [...]

prints the README's table from ``--out`` files.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import math
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

from pnp_twin.policies.registry import make_policy
from pnp_twin.twin.errors import ScenarioError
from pnp_twin.twin.loader import load_scenario, parse_sets
from pnp_twin.twin.run import simulate
from pnp_twin.twin.stats import t_interval

RULES = ("FIFO", "LIFO", "SD", "LD", "SPT")
RESAMPLES = 10_000


def one(job: tuple[str, tuple[str, ...], str, int]) -> dict[str, Any]:
    """One run: gripping rate, decisions and CPU ms per decision of the policy's choose."""
    scenario_name, sets, spec, seed = job
    import torch

    torch.set_num_threads(1)
    scenario = load_scenario(scenario_name, parse_sets(sets) or None)
    policy = make_policy(spec, scenario.robots.count)
    spent = [0.0, 0]
    stats = getattr(policy, "stats", None)
    if stats is None and spec.startswith("hdqn"):
        inner = policy.choose

        def timed(decision: Any) -> int:
            t0 = time.process_time()
            k = inner(decision)
            spent[0] += time.process_time() - t0
            spent[1] += 1
            return k

        policy.choose = timed  # type: ignore[method-assign]
    result = simulate(scenario, policy, seed=seed, engine="fast")
    out: dict[str, Any] = {"seed": seed, "gripping_rate": float(result.kpis["gripping_rate"])}
    if stats is not None:
        s = stats()
        out["decisions"], out["cpu_ms_per_decision"] = s["decisions"], s["cpu_ms_per_decision"]
    elif spent[1]:
        out["decisions"], out["cpu_ms_per_decision"] = spent[1], 1000.0 * spent[0] / spent[1]
    return out


def share_interval(
    policy: np.ndarray, look: np.ndarray, best: np.ndarray, seed: int = 0
) -> tuple[float, float, float]:
    """The share ``mean(policy - best) / mean(look - best)`` and its 95 % paired bootstrap
    percentile interval over the seeds."""
    a, b = policy - best, look - best
    share = float(a.mean() / b.mean())
    rng = np.random.default_rng(seed)
    idx = rng.integers(0, len(a), size=(RESAMPLES, len(a)))
    ratios = a[idx].mean(axis=1) / b[idx].mean(axis=1)
    lo, hi = np.percentile(ratios, [2.5, 97.5])
    return share, float(lo), float(hi)


def _key(scenario: str, sets: tuple[str, ...], spec: str, seed: int) -> str:
    text = json.dumps([scenario, list(sets), spec, seed])
    return hashlib.sha256(text.encode()).hexdigest()[:20]


def measure(
    scenario: str,
    sets: tuple[str, ...],
    policies: list[str],
    seeds: int,
    lookahead: str,
    workers: int,
    cache: Path | None,
    cpu_rounds: int = 3,
    cpu_duration: float = 120.0,
    first_seed: int = 0,
) -> dict[str, Any]:
    specs = [*RULES, lookahead, *policies]
    seed_list = list(range(first_seed, first_seed + seeds))
    jobs = [(scenario, sets, spec, s) for spec in specs for s in seed_list]
    results: dict[int, dict[str, Any]] = {}
    todo = []
    for i, job in enumerate(jobs):
        path = None if cache is None else cache / f"{_key(*job)}.json"
        reuse = path is not None and path.is_file() and not job[2].startswith("hdqn")
        if reuse:
            assert path is not None
            results[i] = json.loads(path.read_text())
        else:
            todo.append(i)
    if workers > 1:
        from pnp_twin.parallel import pool_map_ordered

        got = pool_map_ordered(one, [jobs[i] for i in todo], workers, ())
    else:
        got = [one(jobs[i]) for i in todo]
    for i, r in zip(todo, got, strict=True):
        results[i] = r
        if cache is not None:
            cache.mkdir(parents=True, exist_ok=True)
            (cache / f"{_key(*jobs[i])}.json").write_text(json.dumps(r))
    per = {spec: [results[j * seeds + s] for s in range(seeds)] for j, spec in enumerate(specs)}
    g = {spec: np.array([r["gripping_rate"] for r in rows]) for spec, rows in per.items()}
    best = max(RULES, key=lambda r: (g[r].mean(), -RULES.index(r)))

    def entry(spec: str) -> dict[str, Any]:
        mean, lo, hi = t_interval(g[spec])
        gain, glo, ghi = t_interval(g[spec] - g[best])
        cpu = [r["cpu_ms_per_decision"] for r in per[spec] if "cpu_ms_per_decision" in r]
        dec = [r["decisions"] for r in per[spec] if "decisions" in r]
        out = {"policy": spec, "gripping_rate": mean, "ci_low": lo, "ci_high": hi}
        out |= {"gain": gain, "gain_ci_low": glo, "gain_ci_high": ghi}
        if cpu:  # CPU per decision over all the seeds' decisions
            out["cpu_ms_per_decision"] = float(np.dot(cpu, dec) / np.sum(dec))
        return out

    look = entry(lookahead)
    if cpu_rounds:
        cpu = measure_cpu(scenario, sets, policies, lookahead, cpu_rounds, cpu_duration)
        look["cpu_ms_per_decision"] = cpu[lookahead]
    students = []
    for spec in policies:
        e = entry(spec)
        if cpu_rounds:
            e["cpu_ms_per_decision"] = cpu[spec]
        e["share"], e["share_ci_low"], e["share_ci_high"] = share_interval(
            g[spec], g[lookahead], g[best]
        )
        if "cpu_ms_per_decision" in e and "cpu_ms_per_decision" in look:
            e["cpu_ratio"] = e["cpu_ms_per_decision"] / look["cpu_ms_per_decision"]
        students.append(e)
    return {
        "scenario": scenario,
        "sets": list(sets),
        "seeds": seed_list,
        "cpu": {
            "rounds": cpu_rounds,
            "duration": cpu_duration,
            "seeds": "100 + round",
            "warm_up": "one uncounted run of each, seed 99",
        },
        "best_rule": entry(best),
        "lookahead": look,
        "policies": students,
        "rules": [entry(r) for r in RULES],
    }


def measure_cpu(
    scenario: str,
    sets: tuple[str, ...],
    policies: list[str],
    lookahead: str,
    rounds: int,
    duration: float,
) -> dict[str, float]:
    """CPU ms per decision of the lookahead and each policy, interleaved run by run."""
    specs = [lookahead, *policies]
    cpu = dict.fromkeys(specs, 0.0)
    decisions = dict.fromkeys(specs, 0)
    timed = (*sets, f"duration={duration:g}")
    for spec in specs:  # uncounted: load each one's compiled code
        one((scenario, timed, spec, 99))
    for r in range(rounds):
        for spec in specs:
            got = one((scenario, timed, spec, 100 + r))
            cpu[spec] += got["cpu_ms_per_decision"] * got["decisions"]
            decisions[spec] += got["decisions"]
    return {spec: cpu[spec] / decisions[spec] for spec in specs}


def _fmt(e: dict[str, Any]) -> str:
    s = f"{e['policy']}: G {e['gripping_rate']:.2f}, gain {e['gain']:+.2f} "
    s += f"[{e['gain_ci_low']:+.2f}, {e['gain_ci_high']:+.2f}]"
    if "share" in e:
        s += f", share {100 * e['share']:.0f} % [{100 * e['share_ci_low']:.0f}, "
        s += f"{100 * e['share_ci_high']:.0f}]"
    if not math.isnan(e.get("cpu_ms_per_decision", math.nan)):
        s += f", {1000 * e['cpu_ms_per_decision']:.0f} us/decision"
    if "cpu_ratio" in e:
        s += f" ({e['cpu_ratio']:.3f} of the lookahead's)"
    return s


def table(paths: list[Path]) -> str:
    """The README's table from ``--out`` files: one row per line (its scenario and sets) and
    student."""
    lines = [
        "| line | seeds | best rule, G % | lookahead | student | student's gain | share of the "
        "lookahead's gain | CPU us/decision, student / lookahead (ratio) |",
        "| --- | --- | --- | --- | --- | --- | --- | --- |",
    ]
    for path in paths:
        d = json.loads(path.read_text(encoding="utf-8"))
        name = " ".join([d["scenario"], *d["sets"]])
        b, la = d["best_rule"], d["lookahead"]
        look = f"{la['gain']:+.2f} [{la['gain_ci_low']:+.2f}, {la['gain_ci_high']:+.2f}]"
        for p in d["policies"]:
            gain = f"{p['gain']:+.2f} [{p['gain_ci_low']:+.2f}, {p['gain_ci_high']:+.2f}]"
            share = f"**{100 * p['share']:.0f} %** [{100 * p['share_ci_low']:.0f}, "
            share += f"{100 * p['share_ci_high']:.0f}]"
            cpu = f"{1000 * p['cpu_ms_per_decision']:.0f} / "
            cpu += f"{1000 * la['cpu_ms_per_decision']:.0f} ({p['cpu_ratio']:.3f})"
            student = p["policy"].removeprefix("hdqn:")
            row = [name, str(len(d["seeds"])), f"{b['policy']} {b['gripping_rate']:.2f}", look]
            lines.append("| " + " | ".join([*row, f"`{student}`", gain, share, cpu]) + " |")
    return "\n".join(lines)


def main() -> None:
    argv = sys.argv[1:]
    if argv[:1] == ["--table"]:
        print(table([Path(p) for p in argv[1:]]))
        return
    sets = tuple(argv[i + 1] for i, a in enumerate(argv) if a == "--set")
    rest = [a for i, a in enumerate(argv) if a != "--set" and (i == 0 or argv[i - 1] != "--set")]
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scenario")
    ap.add_argument("--policy", action="append", default=[])
    ap.add_argument("--seeds", type=int, default=20)
    ap.add_argument("--first-seed", type=int, default=0, help="seeds FIRST..FIRST+N-1")
    ap.add_argument("--lookahead", default="lookahead:K=16,H=1,base=auto")
    ap.add_argument("--workers", type=int, default=1)
    ap.add_argument("--cache", type=Path, default=None)
    ap.add_argument("--cpu-rounds", type=int, default=3)
    ap.add_argument("--cpu-duration", type=float, default=120.0)
    ap.add_argument("--json", action="store_true")
    ap.add_argument("--out", type=Path, default=None, help="also write the JSON here")
    a = ap.parse_args(rest)
    try:
        warmup = load_scenario(a.scenario, parse_sets(sets) or None).warmup
    except ScenarioError as e:
        ap.error(str(e))
    if a.cpu_rounds and a.cpu_duration <= warmup:
        ap.error(f"--cpu-duration: {a.cpu_duration:g} s; must exceed the warmup ({warmup:g} s)")
    out = measure(
        a.scenario,
        sets,
        a.policy,
        a.seeds,
        a.lookahead,
        a.workers,
        a.cache,
        a.cpu_rounds,
        a.cpu_duration,
        a.first_seed,
    )
    if a.out is not None:
        a.out.parent.mkdir(parents=True, exist_ok=True)
        a.out.write_text(json.dumps(out, indent=2) + "\n", encoding="utf-8")
    if a.json:
        print(json.dumps(out, indent=2))
        return
    last = a.first_seed + a.seeds - 1
    print(" ".join([a.scenario, *(f"--set {s}" for s in sets)]), f"seeds {a.first_seed}-{last}")
    print("best rule", _fmt(out["best_rule"]))
    print("lookahead", _fmt(out["lookahead"]))
    for e in out["policies"]:
        print(_fmt(e))


if __name__ == "__main__":
    main()
