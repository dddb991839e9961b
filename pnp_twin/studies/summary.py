"""Summaries of a results table: means with t-intervals, paired differences, best policy.

Replications use common random numbers, so differences between policies at one grid point
are paired by replication: the interval of the mean difference is much narrower than the
two separate intervals suggest.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import pandas as pd

from pnp_twin.twin.stats import t_interval

KPIS = ("gripping_rate", "throughput", "efficiency", "utilisation")
# G in %, efficiency and utilisation as fractions (the CSV convention, docs/study_format.md)
BOUNDS = {"gripping_rate": (0.0, 100.0), "efficiency": (0.0, 1.0), "utilisation": (0.0, 1.0)}


def summarise(results: pd.DataFrame, grid: Sequence[str], confidence: float = 0.95) -> pd.DataFrame:
    """One row per point x policy: grid columns, policy, n, and mean/CI of each KPI."""
    rows = []
    for (point, policy), g in results.groupby(["point", "policy"], sort=True):
        row = {"point": point, **{c: g[c].iloc[0] for c in grid}, "policy": policy, "n": len(g)}
        for kpi in KPIS:
            mean, low, high = t_interval(g[kpi].to_numpy(), confidence)
            if kpi in BOUNDS:  # a bounded KPI: its interval cannot leave the bounds
                low, high = max(low, BOUNDS[kpi][0]), min(high, BOUNDS[kpi][1])
            row.update({f"{kpi}_mean": mean, f"{kpi}_ci_low": low, f"{kpi}_ci_high": high})
        rows.append(row)
    return pd.DataFrame(rows)


def best_policies(summary: pd.DataFrame, grid: Sequence[str]) -> pd.DataFrame:
    """One row per point: the policy with the highest mean gripping rate (first on ties)."""
    rows = []
    for point, g in summary.groupby("point", sort=True):
        top = (
            g.loc[g["gripping_rate_mean"].idxmax()]
            if g["gripping_rate_mean"].notna().any()
            else g.iloc[0]
        )
        rows.append(
            {
                "point": point,
                **{c: top[c] for c in grid},
                "policy": top["policy"],
                "gripping_rate_mean": top["gripping_rate_mean"],
            }
        )
    return pd.DataFrame(rows)


def paired_differences(
    results: pd.DataFrame,
    best: pd.DataFrame,
    grid: Sequence[str],
    confidence: float = 0.95,
) -> pd.DataFrame:
    """Each policy minus the point's best policy, in gripping-rate points, paired by replication."""
    rows = []
    reference = dict(zip(best["point"], best["policy"], strict=True))
    for (point, policy), g in results.groupby(["point", "policy"], sort=True):
        ref = reference[point]
        at = results[(results["point"] == point) & (results["policy"] == ref)]
        mine = g.set_index("replication")["gripping_rate"]
        theirs = at.set_index("replication")["gripping_rate"]
        diff = (mine - theirs).dropna()
        mean, low, high = t_interval(diff.to_numpy(), confidence)
        rows.append(
            {
                "point": point,
                **{c: g[c].iloc[0] for c in grid},
                "policy": policy,
                "reference": ref,
                "diff_mean": mean,
                "diff_ci_low": low,
                "diff_ci_high": high,
                "n": len(diff),
            }
        )
    return pd.DataFrame(rows)


def showcase_point(
    best: pd.DataFrame, grid: Mapping[str, Sequence[Any]], scenario: Mapping[str, Any]
) -> tuple[int, str]:
    """(point, policy) of the run a sweep's report shows up close: the base line (each swept
    parameter at the scenario's own value, else the middle of its values, as the report's
    reference point) with its best policy; point 0 when ``best`` lacks it."""
    want = {}
    for path, values in grid.items():
        node: Any = scenario
        for key in path.split("."):
            node = node.get(key) if isinstance(node, Mapping) else None
        values = sorted(values)
        want[path] = node if node in values else values[(len(values) - 1) // 2]
    mask = pd.Series(True, index=best.index)
    for path, value in want.items():
        mask &= best[path] == value
    row = best[mask].iloc[0] if mask.any() else best.iloc[0]
    return int(row["point"]), str(row["policy"])
