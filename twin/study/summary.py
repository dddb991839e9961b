"""Summaries of a results table: means with t-intervals, paired differences, best policy.

Replications use common random numbers, so differences between policies at one grid point
are paired by replication: the interval of the mean difference is much narrower than the
two separate intervals suggest.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
import pandas as pd

KPIS = ("gripping_rate", "throughput", "efficiency", "utilisation")


def _betacf(a: float, b: float, x: float) -> float:
    """Continued fraction of the regularised incomplete beta (modified Lentz)."""
    tiny = 1e-300
    c, d = 1.0, 1.0 - (a + b) * x / (a + 1.0)
    d = 1.0 / (d if abs(d) > tiny else tiny)
    h = d
    for m in range(1, 300):
        m2 = 2 * m
        for num in (
            m * (b - m) * x / ((a + m2 - 1) * (a + m2)),
            -(a + m) * (a + b + m) * x / ((a + m2) * (a + m2 + 1)),
        ):
            d = 1.0 + num * d
            d = 1.0 / (d if abs(d) > tiny else tiny)
            c = 1.0 + num / c
            c = c if abs(c) > tiny else tiny
            h *= d * c
        if abs(d * c - 1.0) < 1e-15:
            break
    return h


def _betainc(a: float, b: float, x: float) -> float:
    """Regularised incomplete beta I_x(a, b)."""
    if x <= 0.0:
        return 0.0
    if x >= 1.0:
        return 1.0
    lbeta = math.lgamma(a + b) - math.lgamma(a) - math.lgamma(b)
    front = math.exp(lbeta + a * math.log(x) + b * math.log1p(-x))
    if x < (a + 1.0) / (a + b + 2.0):
        return front * _betacf(a, b, x) / a
    return 1.0 - front * _betacf(b, a, 1.0 - x) / b


def t_cdf(t: float, df: float) -> float:
    """Student's t distribution function."""
    tail = 0.5 * _betainc(df / 2.0, 0.5, df / (df + t * t))
    return 1.0 - tail if t >= 0 else tail


def t_quantile(p: float, df: float) -> float:
    """Student's t quantile (bisection on the distribution function; |error| < 1e-10)."""
    if not 0.0 < p < 1.0:
        raise ValueError(f"p: {p} must be in (0, 1)")
    lo, hi = -1.0, 1.0
    while t_cdf(lo, df) > p:
        lo *= 2.0
    while t_cdf(hi, df) < p:
        hi *= 2.0
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if t_cdf(mid, df) < p:
            lo = mid
        else:
            hi = mid
        if hi - lo < 1e-12:
            break
    return 0.5 * (lo + hi)


def t_interval(values: Sequence[float], confidence: float = 0.95) -> tuple[float, float, float]:
    """(mean, low, high): the t-interval of the mean; NaN bounds below two values."""
    x = np.asarray(values, dtype=float)
    x = x[~np.isnan(x)]
    n = len(x)
    if n == 0:
        return math.nan, math.nan, math.nan
    mean = float(x.mean())
    if n < 2:
        return mean, math.nan, math.nan
    half = t_quantile(0.5 + confidence / 2.0, n - 1) * float(x.std(ddof=1)) / math.sqrt(n)
    return mean, mean - half, mean + half


def summarise(results: pd.DataFrame, grid: Sequence[str], confidence: float = 0.95) -> pd.DataFrame:
    """One row per point x policy: grid columns, policy, n, and mean/CI of each KPI."""
    rows = []
    for (point, policy), g in results.groupby(["point", "policy"], sort=True):
        row = {"point": point, **{c: g[c].iloc[0] for c in grid}, "policy": policy, "n": len(g)}
        for kpi in KPIS:
            mean, low, high = t_interval(g[kpi].to_numpy(), confidence)
            if kpi == "gripping_rate":  # a percentage: the interval cannot leave [0, 100]
                low, high = max(low, 0.0), min(high, 100.0)
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
