"""Study figures (grid, policies, sizing, rule mixes): pure functions from tables to plotly.

No files, no simulation, no state. Every function returns a ``go.Figure`` styled by
``reports.style.style`` so the report looks of a piece; the page assembly
(``reports.layout``) decides which figures a study gets; one run's records are drawn by
``reports.record_figures``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np
import pandas as pd
import plotly.graph_objects as go
from plotly.subplots import make_subplots

from pnp_twin.reports.style import (
    PALETTE,
    cap_percent,
    policy_colors,
    rgba,
    style,
)
from pnp_twin.reports.text import (
    at_point,
    axis_text,
    fmt_pct,
    fmt_value,
    is_category_axis,
    param_label,
    param_value,
    point_label,
    sizing_rows,
    sort_rows,
    sorted_values,
)


def fixed_note(fixed: dict[str, Any]) -> str:
    """'Other parameters: belt speed 0.8 m/s, part flow 12 parts/s'."""
    if not fixed:
        return ""
    held = ", ".join(param_value(p, v, lower=True) for p, v in fixed.items())
    return f"Other parameters: {held}"


def sweep_figure(
    summary: pd.DataFrame,
    param: str,
    fixed: dict[str, Any],
    policies: Sequence[str],
    colors: dict[str, str] | None = None,
) -> go.Figure:
    """Mean gripping rate against ``param`` with a 95 % confidence band per policy."""
    colors = colors or policy_colors(policies)
    rows = at_point(summary, fixed)
    category = is_category_axis(param, rows[param].unique())
    fig = go.Figure()
    for policy in policies:
        d = sort_rows(rows[rows["policy"] == policy], param)
        if d.empty:
            continue
        x = [axis_text(param, v) for v in d[param]] if category else d[param].tolist()
        color = colors[policy]
        lo, hi = d.get("gripping_rate_ci_low"), d.get("gripping_rate_ci_high")
        if lo is not None and hi is not None and np.isfinite(lo).any():
            fig.add_trace(
                go.Scatter(
                    x=x + x[::-1],
                    y=hi.tolist() + lo.tolist()[::-1],
                    mode="lines",
                    fill="toself",
                    fillcolor=rgba(color, min(0.16, max(0.05, 0.24 / len(policies)))),
                    line={"width": 0},
                    hoverinfo="skip",
                    legendgroup=policy,
                    showlegend=False,
                    name=f"{policy} 95 % CI",
                )
            )
        half = (hi - lo) / 2 if lo is not None and hi is not None else d["gripping_rate_mean"] * 0
        fig.add_trace(
            go.Scatter(
                x=x,
                y=d["gripping_rate_mean"],
                mode="lines+markers",
                name=policy,
                legendgroup=policy,
                line={"color": color, "width": 2.5},
                marker={"size": 8},
                customdata=np.column_stack([half.fillna(0).to_numpy()]),
                hovertemplate=f"<b>{policy}</b><br>{param_label(param)}: %{{x}}<br>"
                "G = %{y:.1f} % ± %{customdata[0]:.1f}<extra></extra>",
            )
        )
    values = sorted_values(param, rows[param].unique().tolist())
    if category:  # no breakdowns is an MTBF of infinity: drawn last, never at 0
        fig.update_xaxes(
            title=param_label(param),
            type="category",
            categoryorder="array",
            categoryarray=[axis_text(param, v) for v in values],
        )
    else:
        fig.update_xaxes(title=param_label(param), tickvals=values)
    fig.update_yaxes(title="Gripping rate (%)", ticksuffix=" %")
    mean = rows["gripping_rate_mean"]
    cap_percent(
        fig,
        [*mean, *rows.get("gripping_rate_ci_low", mean)],
        [*mean, *rows.get("gripping_rate_ci_high", mean)],
    )
    title = f"Gripping rate against {param_label(param, unit=False).lower()}"
    note = fixed_note(fixed)
    return style(fig, title, (note + " · bands: 95 % CI") if note else "Bands: 95 % CI")


def heatmap_figure(
    best: pd.DataFrame,
    x: str,
    y: str,
    facet: str | None,
    fixed: dict[str, Any],
) -> go.Figure:
    """Best-policy gripping rate over ``x`` x ``y``, one panel per ``facet`` value (the paper's
    figures 15 to 17 layout), each cell annotated with the rate and the winning policy."""
    rows = at_point(best, fixed)
    facets = sorted_values(facet, rows[facet].unique().tolist()) if facet else [None]
    fig = make_subplots(
        rows=1,
        cols=len(facets),
        shared_yaxes=True,
        horizontal_spacing=0.04,
        subplot_titles=[param_value(facet, f) for f in facets] if facet else None,
    )
    zmin, zmax = float(rows["gripping_rate_mean"].min()), float(rows["gripping_rate_mean"].max())
    if zmax - zmin < 1.0:
        zmin, zmax = zmin - 0.5, zmax + 0.5
    xs = sorted_values(x, rows[x].unique().tolist())
    ys = sorted_values(y, rows[y].unique().tolist())
    for col, value in enumerate(facets, start=1):
        d = rows if facet is None else rows[rows[facet] == value]
        z = d.pivot_table(index=y, columns=x, values="gripping_rate_mean").reindex(
            index=ys, columns=xs
        )
        who = d.pivot_table(index=y, columns=x, values="policy", aggfunc="first").reindex(
            index=ys, columns=xs
        )
        fig.add_trace(
            go.Heatmap(
                x=[axis_text(x, v) for v in xs],
                y=[axis_text(y, v) for v in ys],
                z=z.to_numpy(),
                text=who.fillna("").to_numpy(),
                zmin=zmin,
                zmax=zmax,
                colorscale="RdYlGn",
                showscale=col == len(facets),
                colorbar={"title": {"text": "G (%)"}, "ticksuffix": " %", "thickness": 14},
                texttemplate="<b>%{z:.1f} %</b><br>%{text}",
                textfont={"size": 13},
                xgap=2,
                ygap=2,
                hovertemplate=f"{param_label(x)}: %{{x}}<br>{param_label(y)}: %{{y}}<br>"
                "best: %{text}, G = %{z:.1f} %<extra></extra>",
            ),
            row=1,
            col=col,
        )
        fig.update_xaxes(title=param_label(x), type="category", row=1, col=col)
    fig.update_yaxes(title=param_label(y), type="category", row=1, col=1)
    subtitle = "Best policy per cell and its mean gripping rate"
    if fixed:
        subtitle += " · " + fixed_note(fixed)
    title = (
        f"Gripping rate over {param_label(x, False).lower()} and {param_label(y, False).lower()}"
    )
    return style(fig, title, subtitle, height=400 if len(facets) > 1 else 440, top=110)


def policy_figure(
    paired: pd.DataFrame,
    grid: list[str],
    policies: Sequence[str],
    colors: dict[str, str] | None = None,
) -> go.Figure:
    """Paired difference of each policy's gripping rate to the best policy at each grid
    point, with 95 % CI error bars (the best sits at zero)."""
    colors = colors or policy_colors(policies)
    d = paired[paired["policy"].isin(list(policies))].copy()
    d["label"] = [point_label(r, grid) for _, r in d.iterrows()] if grid else "baseline"
    order = list(dict.fromkeys(d.sort_values(grid)["label"])) if grid else ["baseline"]
    if len(order) == 1:
        return single_point_policy_figure(d, policies, colors)
    fig = go.Figure()
    for policy in policies:
        p = d[d["policy"] == policy].set_index("label").reindex(order).dropna(subset=["policy"])
        if p.empty:
            continue
        fig.add_trace(
            go.Scatter(
                x=p.index.tolist(),
                y=p["diff_mean"],
                mode="markers",
                name=policy,
                marker={"color": colors[policy], "size": 9},
                error_y={
                    "type": "data",
                    "array": (p["diff_ci_high"] - p["diff_mean"]).fillna(0),
                    "arrayminus": (p["diff_mean"] - p["diff_ci_low"]).fillna(0),
                    "thickness": 1.5,
                    "width": 4,
                },
                customdata=p[["reference"]].to_numpy(),
                hovertemplate=f"<b>{policy}</b> at %{{x}}<br>%{{y:+.1f}} points vs "
                "%{customdata[0]}<extra></extra>",
            )
        )
    fig.add_hline(y=0, line={"color": "#9aa5b1", "width": 1, "dash": "dot"})
    fig.update_layout(scattermode="group", scattergap=0.5)
    fig.update_xaxes(type="category", tickangle=-35 if len(order) > 6 else 0)
    fig.update_yaxes(title="G − best policy (points)", zeroline=False)
    return style(
        fig,
        "Policy comparison: gap to the best policy",
        "Paired by replication (common random numbers) · error bars: 95 % CI",
        height=460 if len(order) > 6 else 400,
    )


def single_point_policy_figure(
    paired: pd.DataFrame, policies: Sequence[str], colors: dict[str, str]
) -> go.Figure:
    """The policy comparison of a study with one grid point: one row per policy."""
    d = paired.set_index("policy").reindex([p for p in policies if p in set(paired["policy"])])
    d = d.sort_values("diff_mean")
    fig = go.Figure(
        go.Scatter(
            x=d["diff_mean"],
            y=d.index.tolist(),
            mode="markers",
            marker={"color": [colors[p] for p in d.index], "size": 11},
            error_x={
                "type": "data",
                "array": (d["diff_ci_high"] - d["diff_mean"]).fillna(0),
                "arrayminus": (d["diff_mean"] - d["diff_ci_low"]).fillna(0),
                "thickness": 1.5,
                "width": 5,
            },
            customdata=d[["reference"]].to_numpy(),
            hovertemplate="<b>%{y}</b><br>%{x:+.2f} points vs %{customdata[0]}<extra></extra>",
            showlegend=False,
        )
    )
    fig.add_vline(x=0, line={"color": "#9aa5b1", "width": 1, "dash": "dot"})
    fig.update_xaxes(title="G − best policy (points)", zeroline=False)
    fig.update_yaxes(type="category", automargin=True)
    return style(
        fig,
        "Policy comparison: gap to the best policy",
        "Paired by replication (common random numbers) · error bars: 95 % CI",
        height=max(300, 130 + 34 * len(d)),
    )


def number(value: Any, default: float) -> float:
    """``value`` as a finite float, else ``default``."""
    try:
        x = float(value)
    except (TypeError, ValueError):
        return default
    return x if np.isfinite(x) else default


def sizing_figure(sizing: dict[str, Any]) -> go.Figure:
    """Mean gripping rate per tried value with its CI, one line per condition (breakdowns
    off / on, other swept values), the target line and the answer."""
    param = str(sizing.get("parameter") or "robots.count")
    rows = [r for r in sizing_rows(sizing) if r["value"] is not None and r["mean"] is not None]
    conditions = list(dict.fromkeys(r["condition"] for r in rows))
    fig = go.Figure()
    for i, cond in enumerate(conditions):
        mine = sorted((r for r in rows if r["condition"] == cond), key=lambda r: r["value"])
        y = [float(r["mean"]) for r in mine]
        color = PALETTE[i % len(PALETTE)]
        fig.add_trace(
            go.Scatter(
                x=[r["value"] for r in mine],
                y=y,
                mode="lines+markers",
                name=cond or "mean G",
                line={"color": color, "width": 2},
                marker={
                    "size": 11,
                    "color": ["#2a9d8f" if r["reached"] else "#ffffff" for r in mine],
                    "line": {"width": 1.5, "color": color},
                },
                error_y={
                    "type": "data",
                    "array": [number(r["ci_high"], m) - m for r, m in zip(mine, y, strict=True)],
                    "arrayminus": [
                        m - number(r["ci_low"], m) for r, m in zip(mine, y, strict=True)
                    ],
                    "thickness": 1.2,
                    "color": color,
                },
                customdata=[[r["policy"] or ""] for r in mine],
                hovertemplate=f"{param_label(param)}: %{{x}}<br>G = %{{y:.2f}} %"
                " (%{customdata[0]})<extra>" + (cond or "") + "</extra>",
                showlegend=bool(cond),
            )
        )
    target = sizing.get("target")
    if target is not None:
        fig.add_hline(
            y=float(target),
            line={"color": "#c0392b", "dash": "dash"},
            annotation_text=f"target {fmt_pct(float(target))}",
            annotation_position="bottom right",
        )
    answer = sizing.get("answer")
    values = sorted({r["value"] for r in rows})
    if answer is not None and answer in values:
        fig.add_vline(
            x=answer,
            line={"color": "#2a9d8f", "width": 1, "dash": "dot"},
            annotation_text=f"answer: {fmt_value(answer)}",
            annotation_position="bottom left",
        )
    fig.update_xaxes(title=param_label(param), tickvals=values)
    fig.update_yaxes(title="Gripping rate (%)", ticksuffix=" %")
    lows = [number(r["ci_low"], float(r["mean"])) for r in rows]
    highs = [number(r["ci_high"], float(r["mean"])) for r in rows]
    goal = [float(target)] if target is not None else []
    cap_percent(fig, [*lows, *goal], [*highs, *goal])
    return style(
        fig,
        "Sizing: gripping rate against " + param_label(param, False).lower(),
        f"Target G ≥ {fmt_pct(number(target, math.nan))} with "
        f"{100 * number(sizing.get('confidence'), 0.95):g} % confidence: filled markers reach it "
        "· error bars: CI of the rule to run at each point (Bonferroni over the rules)",
    )


def mix_figure(mix: dict[str, Any], top: int = 15) -> go.Figure:
    """The best rule mixes, best at the top, with their 95 % confidence intervals."""
    ranked = (mix.get("ranked") or [])[:top][::-1]
    names = [str(r["mix"]) for r in ranked]
    mean = [float(r["gripping_rate_mean"]) for r in ranked]
    hi = [number(r.get("ci_high"), m) - m for r, m in zip(ranked, mean, strict=True)]
    lo = [m - number(r.get("ci_low"), m) for r, m in zip(ranked, mean, strict=True)]
    colors = ["#2a9d8f" if i == len(names) - 1 else "#1f4e79" for i in range(len(names))]
    fig = go.Figure(
        go.Scatter(
            y=names,
            x=mean,
            mode="markers+text",
            marker={"color": colors, "size": 11},
            error_x={"type": "data", "array": hi, "arrayminus": lo, "thickness": 1.5, "width": 5},
            text=[fmt_pct(m) for m in mean],
            textposition="top center",
            textfont={"size": 11, "color": "#5f6b7a"},
            hovertemplate="%{y}: G = %{x:.2f} %<extra></extra>",
            showlegend=False,
        )
    )
    left = min((m - d for m, d in zip(mean, lo, strict=True)), default=0)
    right = max((m + d for m, d in zip(mean, hi, strict=True)), default=100)
    pad = max(1.0, 0.08 * (right - left))
    fig.update_xaxes(title="Mean gripping rate (%)", range=[left - pad, right + pad])
    fig.update_yaxes(type="category", automargin=True, range=[-0.6, len(names) - 0.2])
    return style(
        fig,
        f"Rule-mix ranking: the best {len(names)}",
        "Per-robot rules, upstream robot first · error bars: 95 % CI",
        height=max(320, 120 + 40 * len(names)),
    )


def layout_figure(sizing: dict[str, Any]) -> go.Figure:
    """The belt and workspaces each robot count ran on (sizing.json's layout), the answer
    highlighted: what ``--layout extend`` (longer belt) or ``share`` (narrower workspaces)
    means on the floor."""
    layout = sizing.get("layout") or {}
    counts = sorted((layout.get("counts") or {}).items(), key=lambda kv: int(kv[0]))
    answer = sizing.get("answer")
    fig = go.Figure()
    shapes: list[dict[str, Any]] = []
    names = []
    for row, (n, c) in enumerate(counts):
        ws = float(c["workspace_length"])
        name = f"{n} robots" + (" (answer)" if answer is not None and int(n) == answer else "")
        names.append(name)
        shapes.append(
            {
                "type": "rect",
                "x0": 0,
                "x1": float(c["belt_length"]),
                "y0": row - 0.32,
                "y1": row + 0.32,
                "fillcolor": "#eef1f5",
                "line": {"color": "#9aa5b1", "width": 1},
                "layer": "below",
            }
        )
        strong = answer is not None and int(n) == answer
        for i, (a, b) in enumerate(c["workspaces"]):
            color = PALETTE[i % len(PALETTE)]
            shapes.append(
                {
                    "type": "rect",
                    "x0": float(a),
                    "x1": float(b),
                    "y0": row - 0.22,
                    "y1": row + 0.22,
                    "fillcolor": rgba(color, 0.55 if strong else 0.25),
                    "line": {"color": color, "width": 1},
                }
            )
        fig.add_trace(
            go.Scatter(
                x=[float(c["belt_length"])],
                y=[row],
                mode="text",
                text=[f" {float(c['belt_length']):g} m belt, {ws:.3g} m each"],
                textposition="middle right",
                hoverinfo="skip",
                showlegend=False,
            )
        )
    longest = max((float(c["belt_length"]) for _, c in counts), default=1.0)
    fig.update_layout(shapes=shapes)
    fig.update_xaxes(title="Along the belt, x (m)", range=[-0.05, longest * 1.45])
    fig.update_yaxes(
        tickvals=list(range(len(names))),
        ticktext=names,
        range=[-0.7, len(names) - 0.3],
        autorange="reversed",
        showgrid=False,
        zeroline=False,
    )
    mode = str(layout.get("mode", "extend"))
    what = (
        "the belt is kept and shared by narrower workspaces"
        if mode == "share"
        else "each workspace keeps its length and the belt grows"
    )
    return style(
        fig,
        f"Layout: {mode}",
        f"Workspaces (coloured, robot 1 upstream) on the belt (grey) per robot count: {what}",
        height=max(260, 110 + 34 * len(names)),
    )
