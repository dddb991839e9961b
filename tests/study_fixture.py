"""A small but real study folder in the format of ``docs/study_format.md``, for report tests.

It runs ``twin.run.simulate`` over a grid, policies and replications (common random numbers:
replication k uses the same seed everywhere), then computes the summary, paired, best,
records, sizing and mix files with pandas, as the study machinery does. Import it explicitly:
``from tests.study_fixture import make_study``.
"""

from __future__ import annotations

import itertools
import json
import math
import platform
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import plotly
import simpy

from policies import make_policy
from twin import load_scenario, with_overrides
from twin.kpis import flat_kpis
from twin.run import RunResult, simulate

BASELINE = Path(__file__).resolve().parents[1] / "scenarios" / "paper_baseline.toml"
KPIS = ("gripping_rate", "throughput", "efficiency", "utilisation")
# two-sided 95 % Student t quantiles by degrees of freedom (no scipy in the environment)
T975 = {1: 12.706, 2: 4.303, 3: 3.182, 4: 2.776, 5: 2.571, 6: 2.447, 7: 2.365, 8: 2.306}
T975 |= {9: 2.262, 10: 2.228, 15: 2.131, 20: 2.086, 30: 2.042}


def t975(df: int) -> float:
    """The 97.5 % t quantile (the largest tabulated df not above ``df``; 1.96 beyond 30)."""
    if df > 30:
        return 1.96
    return T975[max(k for k in T975 if k <= df)]


def mean_ci(values: Sequence[float]) -> tuple[float, float, float]:
    """Mean and 95 % t-interval; NaN bounds for a single value."""
    x = np.asarray(values, dtype=float)
    m = float(x.mean())
    if len(x) < 2:
        return m, math.nan, math.nan
    half = t975(len(x) - 1) * float(x.std(ddof=1)) / math.sqrt(len(x))
    return m, m - half, m + half


def summarise(results: pd.DataFrame, grid: list[str]) -> pd.DataFrame:
    """summary.csv: one row per point x policy with mean and CI of the four KPIs."""
    rows = []
    for key, d in results.groupby([*grid, "policy"], sort=False):
        key = key if isinstance(key, tuple) else (key,)
        row: dict[str, Any] = dict(zip([*grid, "policy"], key, strict=True))
        row["n"] = len(d)
        for kpi in KPIS:
            row[f"{kpi}_mean"], row[f"{kpi}_ci_low"], row[f"{kpi}_ci_high"] = mean_ci(d[kpi])
        rows.append(row)
    return pd.DataFrame(rows)


def best_of(summary: pd.DataFrame, grid: list[str]) -> pd.DataFrame:
    """best.csv: the policy with the highest mean gripping rate at each point."""
    if not grid:
        return summary.loc[
            [summary["gripping_rate_mean"].idxmax()], ["policy", "gripping_rate_mean"]
        ]
    idx = summary.groupby(grid)["gripping_rate_mean"].idxmax()
    return summary.loc[idx.to_numpy(), [*grid, "policy", "gripping_rate_mean"]].reset_index(
        drop=True
    )


def pair(results: pd.DataFrame, best: pd.DataFrame, grid: list[str]) -> pd.DataFrame:
    """paired.csv: G(policy) - G(best policy) per replication, mean and CI, per point."""
    rows = []
    for _, b in best.iterrows():
        at = results
        for p in grid:
            at = at[at[p] == b[p]]
        ref = at[at["policy"] == b["policy"]].set_index("replication")["gripping_rate"]
        for policy, d in at.groupby("policy", sort=False):
            diff = d.set_index("replication")["gripping_rate"] - ref
            m, lo, hi = mean_ci(diff.dropna())
            rows.append(
                {p: b[p] for p in grid}
                | {"policy": policy, "reference": b["policy"], "diff_mean": m}
                | {"diff_ci_low": lo, "diff_ci_high": hi}
            )
    return pd.DataFrame(rows)


def write_json(path: Path, data: Mapping[str, Any]) -> None:
    path.write_text(json.dumps(data, indent=2, default=float), encoding="utf-8")


def sizing_of(summary: pd.DataFrame, results: pd.DataFrame, flow: float, target: float) -> dict:
    """A sizing.json from a robots.count grid: the smallest count whose CI clears the target."""
    rows = []
    best = summary.loc[summary.groupby("robots.count")["gripping_rate_mean"].idxmax()]
    for _, r in best.sort_values("robots.count").iterrows():
        reached = bool(r["gripping_rate_ci_low"] >= target)
        rows.append(
            {
                "robots.count": int(r["robots.count"]),
                "policy": str(r["policy"]),
                "gripping_rate_mean": float(r["gripping_rate_mean"]),
                "ci_low": float(r["gripping_rate_ci_low"]),
                "ci_high": float(r["gripping_rate_ci_high"]),
                "reached": reached,
            }
        )
    answer = next((r["robots.count"] for r in rows if r["reached"]), None)
    ppas = float(results["r1_capacity"].mean())
    n_min = flow / ppas
    return {
        "target": target,
        "confidence": 0.95,
        "parameter": "robots.count",
        "rows": rows,
        "answer": answer,
        "rule_of_thumb": {
            "part_flow": flow,
            "ppas": ppas,
            "n_min": n_min,
            "margin": 0.2,
            "n_recommended": math.ceil(n_min * 1.2),
        },
        "breakdown": {
            "availability": 0.97,
            "n_with_failures": None if answer is None else answer + 1,
        },
        "text": f"{answer} robots reach {target} %." if answer else "Target not reached.",
    }


def make_study(
    folder: Path,
    grid: Mapping[str, Sequence[Any]] | None = None,
    policies: Sequence[str] = ("SD", "FIFO"),
    replications: int = 2,
    duration: float = 60.0,
    warmup: float = 10.0,
    kind: str = "sweep",
    records: bool = True,
    target: float = 90.0,
    master_seed: int = 7,
    base: Mapping[str, Any] | None = None,
) -> Path:
    """Run the study and write its folder; returns ``folder``."""
    grid = dict(grid if grid is not None else {})
    paths = list(grid)
    folder.mkdir(parents=True, exist_ok=True)
    overrides = {"duration": duration, "warmup": warmup, **(base or {})}
    scenario = load_scenario(BASELINE, overrides=overrides)
    seeds = [
        int(s.generate_state(1)[0]) for s in np.random.SeedSequence(master_seed).spawn(replications)
    ]
    rows, kept = [], {}
    for point, values in enumerate(itertools.product(*grid.values())):
        at = dict(zip(paths, values, strict=True))
        sc = with_overrides(scenario, at) if at else scenario
        for policy in policies:
            for rep, seed in enumerate(seeds):
                r: RunResult = simulate(sc, make_policy(policy), seed=seed, policy_name=policy)
                if point == 0 and rep == 0:
                    kept[policy] = (r, sc)
                rows.append(
                    {"run_id": f"p{point}-{policy}-r{rep}", "point": point, **at}
                    | {"policy": policy, "replication": rep, "seed": seed}
                    | {
                        k: v
                        for k, v in flat_kpis(r.kpis).items()
                        if k not in ("scenario", "policy", "seed")
                    }
                    | {"wall_time": r.wall_time}
                )
    results = pd.DataFrame(rows)
    results = results.sort_values(["point", "policy", "replication"]).reset_index(drop=True)
    results.to_parquet(folder / "results.parquet", index=False)
    results.to_csv(folder / "results.csv", index=False)
    summary = summarise(results, paths)
    summary.to_csv(folder / "summary.csv", index=False)
    best = best_of(summary, paths)
    best.to_csv(folder / "best.csv", index=False)
    pair(results, best, paths).to_csv(folder / "paired.csv", index=False)
    if records:
        top = str(best.iloc[0]["policy"])
        run, sc = kept[top]
        (folder / "records").mkdir(exist_ok=True)
        run.parts.to_parquet(folder / "records" / "parts.parquet", index=False)
        run.spans.to_parquet(folder / "records" / "spans.parquet", index=False)
        write_json(
            folder / "records" / "run.json",
            {"point": 0, "policy": top, "replication": 0, "seed": seeds[0]}
            | {"scenario": sc.model_dump(mode="json")},
        )
    if kind == "size":
        write_json(
            folder / "sizing.json", sizing_of(summary, results, scenario.feeder.rate, target)
        )
    if kind == "mix":
        ranked = summary.sort_values("gripping_rate_mean", ascending=False)
        write_json(
            folder / "mix.json",
            {
                "method": "exhaustive",
                "ranked": [
                    {"mix": r["policy"], "gripping_rate_mean": r["gripping_rate_mean"]}
                    | {"ci_low": r["gripping_rate_ci_low"], "ci_high": r["gripping_rate_ci_high"]}
                    for _, r in ranked.iterrows()
                ],
                "best": str(ranked.iloc[0]["policy"]),
                "evaluated": len(ranked),
            },
        )
    write_json(
        folder / "meta.json",
        {
            "kind": kind,
            "scenario": scenario.model_dump(mode="json"),
            "scenario_name": scenario.name,
            "master_seed": master_seed,
            "replications": replications,
            "duration": duration,
            "warmup": warmup,
            "grid": {k: list(v) for k, v in grid.items()},
            "policies": list(policies),
            "versions": {
                "pnp_twin": "0.1.0",
                "python": platform.python_version(),
                "simpy": simpy.__version__,
                "numpy": np.__version__,
                "pandas": pd.__version__,
                "plotly": plotly.__version__,
            },
            "started_at": "2025-01-01T00:00:00Z",
            "finished_at": "2025-01-01T00:00:05Z",
            "wall_time": float(results["wall_time"].sum()),
            "workers": 1,
            "backend": "local",
            "command": f"pnp-twin {kind} {BASELINE.name} --out {folder.name}",
        },
    )
    return folder
