"""Warm-up guidance: Welch's plot of the gripping rate over time, and a drift check.

Welch's method (Welch 1983; Law, *Simulation Modeling and Analysis*, ch. 9): average the
KPI over replications at each time bin, smooth the average with a centred moving average,
and choose the warm-up where the curve settles. Each run's row carries its G per time bin
(``welch_gripping_rate``, see ``twin.kpis``), so the report needs no simulation.

The drift check: for each replication, the mean G of the second half of the measured window
minus that of the first half, paired by replication; a t-interval that excludes zero, with a
mean change of at least ``DRIFT_POINTS``, says the KPI is still drifting after the warm-up.
"""

from __future__ import annotations

import json
import math
import warnings
from typing import Any

import numpy as np
import pandas as pd
import plotly.graph_objects as go

from pnp_twin.reports.style import PALETTE, cap_percent, rgba, style
from pnp_twin.twin.stats import t_interval

COLUMN = "welch_gripping_rate"
DRIFT_POINTS = 0.5  # a change smaller than this is not worth a warning


def series_matrix(values: Any) -> np.ndarray:
    """Replications x bins from the JSON text cells (or lists) of one configuration."""
    rows = [json.loads(v) if isinstance(v, str) else list(v) for v in values]
    rows = [[math.nan if x is None else float(x) for x in r] for r in rows]
    width = max((len(r) for r in rows), default=0)
    return np.array([r + [math.nan] * (width - len(r)) for r in rows], dtype=float)


def moving_average(x: np.ndarray, window: int) -> np.ndarray:
    """Welch's centred moving average: near the start the window shrinks, and the last
    ``window`` bins, which a centred window cannot cover, are left out (NaN), as Welch's."""
    out = np.full(len(x), np.nan)
    for i in range(len(x) - window):
        w = min(window, i)
        part = x[i - w : i + w + 1]
        if np.isfinite(part).any():
            out[i] = float(np.nanmean(part))
    return out


def two_halves(a: Any, b: Any) -> tuple[float, float, float]:
    """mean(b) - mean(a) with a 95 % normal-approximation interval (Welch's standard error)."""
    x, y = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    x, y = x[np.isfinite(x)], y[np.isfinite(y)]
    if len(x) < 2 or len(y) < 2:
        return math.nan, math.nan, math.nan
    d = float(y.mean() - x.mean())
    se = math.sqrt(float(x.var(ddof=1)) / len(x) + float(y.var(ddof=1)) / len(y))
    return d, d - 1.96 * se, d + 1.96 * se


def analyse(
    matrix: np.ndarray, duration: float, warmup: float, confidence: float = 0.95
) -> dict[str, Any]:
    """Mean curve, its moving average, bin centres and the drift after the warm-up."""
    reps, bins = matrix.shape
    width = duration / bins
    t = (np.arange(bins) + 0.5) * width
    with warnings.catch_warnings():  # a bin no part was fed in, in any replication
        warnings.simplefilter("ignore", RuntimeWarning)
        mean = np.nanmean(matrix, axis=0) if reps else np.full(bins, np.nan)
    window = max(1, bins // 12)
    after = np.flatnonzero(t >= warmup)
    first, second = np.array_split(after, 2) if len(after) >= 2 else (after, after[:0])
    if reps >= 2:  # paired by replication
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            diffs = np.nanmean(matrix[:, second], axis=1) - np.nanmean(matrix[:, first], axis=1)
        d, low, high = t_interval(diffs.tolist(), confidence)
    else:  # one run: the two halves' bins as two samples (normal approximation)
        d, low, high = two_halves(
            matrix[0, first] if reps else [], matrix[0, second] if reps else []
        )
    drifting = bool(math.isfinite(low) and (low > 0 or high < 0) and abs(d) >= DRIFT_POINTS)
    return {
        "t": t,
        "mean": mean,
        "smooth": moving_average(mean, window),
        "window": window,
        "bin": width,
        "replications": reps,
        "drift": {"change": d, "ci_low": low, "ci_high": high, "drifting": drifting},
    }


def note(a: dict[str, Any], warmup: float) -> str:
    """One sentence on the warm-up chosen and whether G still drifts after it."""
    d = a["drift"]
    if not math.isfinite(d["change"]):
        return f"Warm-up {warmup:g} s; too few parts to judge the drift after it."
    kind = "paired " if a["replications"] >= 2 else ""
    ci = (
        f" ({kind}95 % CI {d['ci_low']:+.2f} to {d['ci_high']:+.2f})"
        if math.isfinite(d["ci_low"])
        else ""
    )
    change = f"G changes by {d['change']:+.2f} points from the first to the second half of the "
    change += f"measured window{ci}"
    if d["drifting"]:
        return (
            f"Warning: G is still drifting after the {warmup:g} s warm-up: {change}. "
            "Lengthen the warm-up (or the run) until the curve is flat after the marker."
        )
    return f"The {warmup:g} s warm-up looks long enough: {change}."


def welch_figure(a: dict[str, Any], warmup: float, duration: float, where: str) -> go.Figure:
    """The mean G per bin (faint), its moving average (bold) and the warm-up marked."""
    fig = go.Figure()
    fig.add_vrect(x0=0, x1=warmup, fillcolor="#8d99ae", opacity=0.12, line_width=0)
    fig.add_trace(
        go.Scatter(
            x=a["t"],
            y=a["mean"],
            mode="lines",
            name="mean over replications",
            line={"color": rgba(PALETTE[0], 0.35), "width": 1},
            hovertemplate="t = %{x:.1f} s: G = %{y:.1f} %<extra></extra>",
        )
    )
    fig.add_trace(
        go.Scatter(
            x=a["t"],
            y=a["smooth"],
            mode="lines",
            name=f"moving average (window {2 * a['window'] + 1} bins)",
            line={"color": PALETTE[1], "width": 2.5},
            hovertemplate="t = %{x:.1f} s: %{y:.1f} %<extra>moving average</extra>",
        )
    )
    fig.add_vline(
        x=warmup,
        line={"color": "#c0392b", "dash": "dash"},
        annotation_text=f"warm-up {warmup:g} s",
        annotation_position="top right",
    )
    fig.update_xaxes(title="Time fed (s)", range=[0, duration])
    fig.update_yaxes(title="Gripping rate (%)", ticksuffix=" %")
    finite = [float(v) for v in a["mean"] if np.isfinite(v)]
    if finite:
        cap_percent(fig, [min(finite)], [max(finite)])
    reps = a["replications"]
    return style(
        fig,
        "Warm-up: Welch's plot of the gripping rate",
        f"{where} · G of the parts fed in each {a['bin']:.3g} s bin, mean of {reps} "
        f"replication{'s' if reps != 1 else ''} · grey: warm-up, not measured",
        height=380,
    )


def welch_items(
    results: pd.DataFrame | None, duration: float, warmup: float, where: str
) -> tuple[go.Figure, str, bool] | None:
    """(figure, note, drifting) for one configuration's runs; None without the series."""
    if results is None or COLUMN not in results.columns or results.empty or duration <= 0:
        return None
    matrix = series_matrix(results[COLUMN].dropna())
    if matrix.size == 0:
        return None
    a = analyse(matrix, duration, warmup)
    return welch_figure(a, warmup, duration, where), note(a, warmup), a["drift"]["drifting"]


__all__ = ["analyse", "moving_average", "note", "series_matrix", "welch_figure", "welch_items"]
