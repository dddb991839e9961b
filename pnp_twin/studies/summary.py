"""Summaries of a results table: means with t-intervals, paired differences, best policy.

Replications use common random numbers, so differences between policies at one grid point
are paired by replication: the interval of the mean difference is much narrower than the
two separate intervals suggest.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
import pandas as pd

from pnp_twin.twin.stats import t_interval, t_quantile

KPIS = ("gripping_rate", "throughput", "efficiency", "utilisation")
# G in %, efficiency and utilisation as fractions (the CSV convention, docs/study_format.md)
BOUNDS = {"gripping_rate": (0.0, 100.0), "efficiency": (0.0, 1.0), "utilisation": (0.0, 1.0)}
BOUNDS |= {"value_rate": (0.0, 100.0), "fill_rate": (0.0, 100.0), "hold": (0.0, 1.0)}


def grouped_intervals(
    values: np.ndarray, starts: np.ndarray, counts: np.ndarray, confidence: float = 0.95
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(mean, low, high) per group of ``values`` (group g is ``values[starts[g]:][:counts[g]]``),
    each exactly :func:`~twin.stats.t_interval`'s double: the groups of one size are stacked
    into one C-contiguous array and reduced along its rows, which numpy sums as it sums a
    single group; groups holding NaN or fewer than two values go through t_interval itself.
    """
    groups = len(counts)
    mean, low, high = (np.full(groups, np.nan) for _ in range(3))
    for n in np.unique(counts):
        at = np.flatnonzero(counts == n)
        block = values[starts[at, None] + np.arange(n)] if n else np.empty((len(at), 0))
        plain = ~np.isnan(block).any(axis=1) if n >= 2 else np.zeros(len(at), bool)
        for g in at[~plain]:
            mean[g], low[g], high[g] = t_interval(values[starts[g] : starts[g] + n], confidence)
        if not plain.any():
            continue
        rows, block = at[plain], np.ascontiguousarray(block[plain])
        m = block.mean(axis=1)
        half = t_quantile(0.5 + confidence / 2.0, int(n) - 1) * block.std(axis=1, ddof=1)
        half /= math.sqrt(n)
        mean[rows], low[rows], high[rows] = m, m - half, m + half
    return mean, low, high


def _groups(frame: pd.DataFrame, keys: list[str]) -> tuple[pd.DataFrame, np.ndarray, np.ndarray]:
    """``frame`` stably sorted by ``keys`` (groupby's order), each group's first row and size."""
    ordered = frame.sort_values(keys, kind="stable")
    codes = ordered[keys].to_numpy()
    new = np.ones(len(ordered), bool)
    new[1:] = (codes[1:] != codes[:-1]).any(axis=1)
    starts = np.flatnonzero(new)
    counts = np.diff(np.append(starts, len(ordered)))
    return ordered.reset_index(drop=True), starts, counts


def _first(ordered: pd.DataFrame, starts: np.ndarray, columns: list[str]) -> dict[str, Any]:
    return {c: ordered[c].iloc[starts].to_numpy() for c in columns}


SHAPE_KPIS = ("value_rate", "fill_rate", "slots_filled_per_s", "hold")
"""Summarised where a line has them: kinds of part (value_rate), an outfeed (the rest)."""


def shape_kpis(results: pd.DataFrame) -> list[str]:
    """The KPIs of a line's shape also summarised: the value rate and each kind's gripping
    rate (%) on a line with kinds of part, the fill rate, slots filled per second and the
    share of time held on a line with an outfeed (lines without have none of these columns,
    and their summary is unchanged)."""
    kinds = [
        c
        for c in results.columns
        if c.startswith("kind_") and c.endswith("_gripping_rate") and results[c].notna().any()
    ]  # a kind no robot picks has no gripping rate: left out
    return [k for k in SHAPE_KPIS if k in results.columns] + kinds


def summarise(results: pd.DataFrame, grid: Sequence[str], confidence: float = 0.95) -> pd.DataFrame:
    """One row per point x policy: grid columns, policy, n, and mean/CI of each KPI
    (vectorised; the same doubles as a t_interval per group)."""
    if results.empty:
        return pd.DataFrame([])
    ordered, starts, counts = _groups(results, ["point", "policy"])
    columns = ["point", *grid, "policy"]
    out: dict[str, Any] = _first(ordered, starts, columns)
    out["n"] = counts.astype(np.int64)
    for kpi in (*KPIS, *shape_kpis(results)):
        values = ordered[kpi].to_numpy(dtype=float)
        mean, low, high = grouped_intervals(values, starts, counts, confidence)
        bounds = BOUNDS.get(kpi, (0.0, 100.0) if kpi.startswith("kind_") else None)
        if bounds is not None:  # a bounded KPI: its interval cannot leave the bounds
            lo, hi = bounds
            low = np.where(lo > low, lo, low)  # max(low, lo), NaN kept as Python's max does
            high = np.where(hi < high, hi, high)
        out.update({f"{kpi}_mean": mean, f"{kpi}_ci_low": low, f"{kpi}_ci_high": high})
    return pd.DataFrame(out)


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
    if results.empty:
        return pd.DataFrame([])
    ordered, starts, counts = _groups(results, ["point", "policy"])
    reference = dict(zip(best["point"], best["policy"], strict=True))
    ref = ordered["point"].map(reference)
    if ref.isna().any():  # as indexing the mapping would
        raise KeyError(ordered["point"][ref.isna()].iloc[0])
    mine = ordered[["point", "policy", "replication", "gripping_rate"]].assign(reference=ref)
    theirs = ordered[["point", "policy", "replication", "gripping_rate"]].rename(
        columns={"policy": "reference", "gripping_rate": "theirs"}
    )
    paired = mine.merge(theirs, on=["point", "reference", "replication"], how="left")
    if len(paired) != len(ordered):
        raise ValueError("paired_differences: a replication appears twice for one policy")
    diff = (paired["gripping_rate"] - paired["theirs"]).to_numpy()
    kept = ~np.isnan(diff)
    group = np.repeat(np.arange(len(counts)), counts)[kept]
    n = np.bincount(group, minlength=len(counts))
    first = np.concatenate(([0], np.cumsum(n)[:-1]))
    mean, low, high = grouped_intervals(diff[kept], first, n, confidence)
    out: dict[str, Any] = _first(ordered, starts, ["point", *grid, "policy"])
    out["reference"] = ref.iloc[starts].to_numpy()
    out.update({"diff_mean": mean, "diff_ci_low": low, "diff_ci_high": high})
    out["n"] = n.astype(np.int64)
    return pd.DataFrame(out)


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
