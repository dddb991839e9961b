"""Pure functions from study tables to plotly figures: no files, no simulation, no state.

Every function returns a ``go.Figure`` styled by ``style`` so the report looks of a piece;
the page assembly (``reports.layout``) decides which figures a study gets.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
import pandas as pd
import plotly.graph_objects as go
from plotly.subplots import make_subplots

from reports.text import (
    at_point,
    fmt_pct,
    fmt_value,
    param_label,
    param_value,
    point_label,
    sizing_rows,
)

FONT = "Inter, 'Segoe UI', Roboto, 'Helvetica Neue', Arial, sans-serif"
PALETTE = (
    "#1f4e79",
    "#e07b39",
    "#2a9d8f",
    "#c0392b",
    "#7b5ea7",
    "#8c6d31",
    "#d45087",
    "#5c7080",
)
STATE_COLORS = {
    "busy": "#2a9d8f",
    "noop": "#e9c46a",
    "wait": "#f4a261",
    "blocked": "#8d99ae",
    "down": "#e63946",
    "interrupted": "#7b5ea7",
}
STATE_LABELS = {
    "busy": "Busy (move, grip, place)",
    "noop": "NooP (no candidate)",
    "wait": "Waiting (synchronous epoch)",
    "blocked": "Blocked (box change)",
    "down": "Down (breakdown)",
    "interrupted": "Interrupted approach",
}
PART_COLORS = {"to be picked": "#1f4e79", "claimed": "#2a9d8f", "missed": "#e63946"}


def policy_colors(policies: Sequence[str]) -> dict[str, str]:
    """One stable colour per policy, in the study's order."""
    return {p: PALETTE[i % len(PALETTE)] for i, p in enumerate(policies)}


def rgba(hex_color: str, alpha: float) -> str:
    """'#1f4e79', 0.2 -> 'rgba(31,78,121,0.2)'."""
    h = hex_color.lstrip("#")
    r, g, b = (int(h[i : i + 2], 16) for i in (0, 2, 4))
    return f"rgba({r},{g},{b},{alpha})"


def style(
    fig: go.Figure, title: str, subtitle: str = "", height: int = 420, top: int = 0
) -> go.Figure:
    """The house look: white template, system fonts, title with a grey subtitle."""
    text = f"<b>{title}</b>"
    if subtitle:
        text += f"<br><span style='font-size:12px;color:#5f6b7a'>{subtitle}</span>"
    fig.update_layout(
        template="plotly_white",
        title={"text": text, "x": 0.0, "xanchor": "left", "font": {"size": 16}},
        font={"family": FONT, "size": 12, "color": "#1d2733"},
        height=height,
        margin={"l": 70, "r": 30, "t": top or (80 if subtitle else 60), "b": 60},
        legend={"orientation": "h", "yanchor": "bottom", "y": 1.0, "xanchor": "right", "x": 1},
        hoverlabel={"font": {"family": FONT}},
    )
    return fig


def cap_percent(fig: go.Figure, lows: Sequence[Any], highs: Sequence[Any]) -> None:
    """Fit a gripping-rate axis to the data but stop it at 100 %: a t-interval of few
    replications can reach past it, but no line can pick more parts than it is given."""

    def finite(xs: Sequence[Any]) -> list[float]:
        return [float(v) for v in xs if v is not None and np.isfinite(float(v))]

    lo, hi = finite(lows), finite(highs)
    if not lo or not hi:
        return
    pad = max(2.0, 0.06 * (max(hi) - min(lo)))
    fig.update_yaxes(range=[max(0.0, min(lo) - pad), min(101.0, max(hi) + pad)])


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
    fig = go.Figure()
    for policy in policies:
        d = rows[rows["policy"] == policy].sort_values(param)
        if d.empty:
            continue
        x = d[param].tolist()
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
    fig.update_xaxes(title=param_label(param), tickvals=sorted(rows[param].unique().tolist()))
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
    facets = sorted(rows[facet].unique().tolist()) if facet else [None]
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
    xs = sorted(rows[x].unique().tolist())
    ys = sorted(rows[y].unique().tolist())
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
                x=[fmt_value(v) for v in xs],
                y=[fmt_value(v) for v in ys],
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


def robot_count(results: pd.DataFrame) -> int:
    """Number of robots from the r{i}_utilisation columns."""
    n = 0
    while f"r{n + 1}_utilisation" in results.columns:
        n += 1
    return n


def robots_figure(results: pd.DataFrame, point: dict[str, Any], policy: str) -> go.Figure:
    """Per robot: time shares (busy / NooP / wait / blocked / down, stacked) and parts passing
    its workspace unpicked, averaged over the replications of one grid point and policy."""
    runs = at_point(results, point)
    runs = runs[runs["policy"] == policy]
    n = robot_count(runs)
    names = [f"Robot {i}" for i in range(1, n + 1)]
    fig = make_subplots(
        rows=1,
        cols=2,
        column_widths=[0.58, 0.42],
        horizontal_spacing=0.1,
        subplot_titles=["Time share per robot", "Parts leaving each workspace unpicked"],
    )
    columns = {"busy": "utilisation", "noop": "noop", "wait": "wait", "blocked": "blocked"}
    columns["down"] = "down"
    for state, col in columns.items():
        share = [100 * float(runs[f"r{i}_{col}"].mean()) for i in range(1, n + 1)]
        if state != "busy" and max(share, default=0) < 0.05:
            continue  # a state no robot was ever in only clutters the legend
        fig.add_trace(
            go.Bar(
                x=names,
                y=share,
                name=STATE_LABELS[state],
                marker_color=STATE_COLORS[state],
                hovertemplate="%{x}: %{y:.1f} %<extra>" + state + "</extra>",
            ),
            row=1,
            col=1,
        )
    passed = [float(runs[f"r{i}_missed"].mean()) for i in range(1, n + 1)]
    picks = [float(runs[f"r{i}_picks"].mean()) for i in range(1, n + 1)]
    fig.add_trace(
        go.Bar(
            x=names,
            y=passed,
            name="Passed unpicked",
            marker_color="#c0392b",
            text=[f"{v:.0f}" for v in passed],
            textposition="outside",
            customdata=np.column_stack([picks]),
            hovertemplate="%{x}: %{y:.1f} parts passed, %{customdata[0]:.0f} picked<extra></extra>",
            showlegend=False,
        ),
        row=1,
        col=2,
    )
    fig.update_layout(barmode="stack")
    fig.update_yaxes(title="Share of the window (%)", ticksuffix=" %", range=[0, 101], row=1, col=1)
    fig.update_yaxes(title="Parts per run", rangemode="tozero", row=1, col=2)
    fig.update_yaxes(range=[0, max(passed, default=1) * 1.18 + 1], row=1, col=2)
    reps = len(runs)
    where = point_label(point, list(point)) if point else "the baseline"
    subtitle = f"{policy} at {where} · mean of {reps} replication{'s' if reps != 1 else ''}"
    fig = style(fig, "Robots: utilisation and missed parts", subtitle, height=450, top=110)
    fig.update_layout(legend={"y": -0.18, "yanchor": "top", "x": 0, "xanchor": "left"})
    fig.update_layout(margin={"b": 90})
    return fig


def merged_spans(spans: pd.DataFrame) -> pd.DataFrame:
    """Consecutive spans of one robot in one state joined into one (NooPs come in ticks)."""
    if spans.empty:
        return spans
    d = spans.sort_values(["robot", "start"]).reset_index(drop=True)
    same = (
        (d["robot"] == d["robot"].shift())
        & (d["state"] == d["state"].shift())
        & ((d["start"] - d["end"].shift()).abs() < 1e-6)
    )
    d["group"] = (~same).cumsum()
    return (
        d.groupby("group")
        .agg(robot=("robot", "first"), state=("state", "first"), start=("start", "min"))
        .join(d.groupby("group")["end"].max())
        .reset_index(drop=True)
    )


def timeline_figure(
    parts: pd.DataFrame, spans: pd.DataFrame, t0: float, t1: float, n_robots: int
) -> go.Figure:
    """Gantt chart of every robot over [t0, t1]: busy cycles (decided_at to placed_at of each
    picked part) and the state spans (NooP, wait, blocked, down, interrupted)."""
    names = [f"Robot {i}" for i in range(1, n_robots + 1)]
    picked = parts[(parts["outcome"] == "picked") & parts["decided_at"].notna()]
    busy = picked[(picked["placed_at"] > t0) & (picked["decided_at"] < t1)]
    rows = [
        pd.DataFrame(
            {
                "robot": busy["robot"].astype(int),
                "state": "busy",
                "start": busy["decided_at"],
                "end": busy["placed_at"],
                "info": [
                    f"part {p} · rule {r}" for p, r in zip(busy["part"], busy["rule"], strict=True)
                ],
            }
        )
    ]
    other = merged_spans(spans)
    if len(other):
        other = other[(other["end"] > t0) & (other["start"] < t1)].copy()
        other["info"] = ""
        rows.append(other)
    d = pd.concat(rows, ignore_index=True)
    d["start"] = d["start"].clip(lower=t0)
    d["end"] = d["end"].clip(upper=t1)
    fig = go.Figure()
    for state in STATE_COLORS:
        s = d[d["state"] == state]
        if s.empty:
            continue
        fig.add_trace(
            go.Bar(
                y=[names[i] for i in s["robot"]],
                x=s["end"] - s["start"],
                base=s["start"],
                orientation="h",
                name=STATE_LABELS[state],
                marker={"color": STATE_COLORS[state], "line": {"width": 0.5, "color": "white"}},
                customdata=np.column_stack([s["start"], s["end"], s["info"]]),
                hovertemplate="%{y} · "
                + state
                + "<br>%{customdata[0]:.2f} – %{customdata[1]:.2f} s<br>%{customdata[2]}"
                "<extra></extra>",
            )
        )
    fig.update_layout(barmode="overlay", bargap=0.35)
    fig.update_yaxes(categoryorder="array", categoryarray=names[::-1])
    fig.update_xaxes(title="Time (s)", range=[t0, t1])
    fig = style(
        fig,
        "Robot activity timeline",
        f"{t1 - t0:.0f} s of the recorded run, from t = {t0:.0f} s · hover a bar for the part "
        "and rule",
        height=max(300, 150 + 55 * n_robots),
    )
    fig.update_layout(legend={"y": -0.2, "yanchor": "top", "x": 0, "xanchor": "left"})
    fig.update_layout(margin={"b": 90})
    return fig


def belt_positions(parts: pd.DataFrame, belt_speed: float, t: float) -> dict[str, pd.DataFrame]:
    """Parts on the belt at instant ``t`` (fed, not yet gripped or gone), by category, with
    their position x = v_b (t - fed_at)."""
    on = parts[(parts["fed_at"] <= t) & (parts["left_at"] > t)].copy()
    on["x"] = belt_speed * (t - on["fed_at"])
    picked = on["outcome"] == "picked"
    claimed = picked & (on["decided_at"] <= t)
    return {
        "to be picked": on[picked & ~claimed],
        "claimed": on[claimed],
        "missed": on[~picked],
    }


def belt_traces(parts: pd.DataFrame, belt_speed: float, t: float) -> list[go.Scatter]:
    """The three part markers traces of one instant (always three, maybe empty)."""
    out = []
    for cat, d in belt_positions(parts, belt_speed, t).items():
        robot = d["robot"].astype("Float64").fillna(-1).astype(int) + 1
        out.append(
            go.Scatter(
                x=d["x"],
                y=d["y"],
                mode="markers",
                name=cat,
                marker={
                    "color": PART_COLORS[cat],
                    "size": 9,
                    "line": {"width": 1, "color": "white"},
                },
                customdata=np.column_stack([d["part"], robot]),
                hovertemplate="part %{customdata[0]}<br>x = %{x:.2f} m, y = %{y:.2f} m"
                + ("<br>robot %{customdata[1]}" if cat != "missed" else "")
                + "<extra>"
                + cat
                + "</extra>",
            )
        )
    return out


def belt_figure(
    parts: pd.DataFrame,
    scenario: dict[str, Any],
    t: float,
    seconds: float = 5.0,
    step: float = 0.1,
) -> go.Figure:
    """The belt seen from above at instant ``t``, workspaces and bins drawn, parts coloured
    by what happens to them; a play button and slider animate the next ``seconds``."""
    belt = scenario.get("belt") or {}
    length, width, speed = (
        float(belt.get("length", 2.4)),
        float(belt.get("width", 0.4)),
        float(belt.get("speed", 0.8)),
    )
    fig = go.Figure(data=belt_traces(parts, speed, t))
    shapes: list[dict[str, Any]] = [
        {
            "type": "rect",
            "x0": 0,
            "x1": length,
            "y0": 0,
            "y1": width,
            "fillcolor": "#eef1f5",
            "line": {"color": "#9aa5b1", "width": 1},
            "layer": "below",
        }
    ]
    for i, ((a, b), (bx, by)) in enumerate(workspace_layout(scenario), start=1):
        color = PALETTE[(i - 1) % len(PALETTE)]
        shapes.append(
            {
                "type": "rect",
                "x0": a,
                "x1": b,
                "y0": 0,
                "y1": width,
                "fillcolor": rgba(color, 0.07),
                "line": {"color": rgba(color, 0.8), "width": 1.5, "dash": "dot"},
                "layer": "below",
            }
        )
        half = 0.045
        shapes.append(
            {
                "type": "rect",
                "x0": bx - half,
                "x1": bx + half,
                "y0": by - half,
                "y1": by + half,
                "fillcolor": rgba(color, 0.25),
                "line": {"color": color, "width": 1},
            }
        )
        fig.add_annotation(
            x=(a + b) / 2, y=by + half + 0.04, text=f"<b>R{i}</b> bin", showarrow=False
        )
    times = np.round(np.arange(t, t + seconds + 1e-9, step), 6)
    fig.frames = [
        go.Frame(data=belt_traces(parts, speed, float(ti)), name=f"{ti:.1f}") for ti in times
    ]
    slider_steps = [
        {
            "args": [
                [f"{ti:.1f}"],
                {"frame": {"duration": 0, "redraw": False}, "mode": "immediate"},
            ],
            "label": f"{ti:.1f}",
            "method": "animate",
        }
        for ti in times
    ]
    play = {"frame": {"duration": int(step * 1000), "redraw": False}, "fromcurrent": True}
    play["transition"] = {"duration": 0}
    fig.update_layout(
        shapes=shapes,
        updatemenus=[
            {
                "type": "buttons",
                "showactive": False,
                "direction": "left",
                "x": 0,
                "y": -0.22,
                "xanchor": "left",
                "yanchor": "top",
                "buttons": [
                    {"label": "▶ Play", "method": "animate", "args": [None, play]},
                    {
                        "label": "❚❚ Pause",
                        "method": "animate",
                        "args": [[None], {"frame": {"duration": 0}, "mode": "immediate"}],
                    },
                ],
            }
        ],
        sliders=[
            {
                "steps": slider_steps,
                "x": 0.16,
                "len": 0.84,
                "y": -0.16,
                "yanchor": "top",
                "currentvalue": {
                    "prefix": "t = ",
                    "suffix": " s",
                    "font": {"size": 13, "color": "#1d2733"},
                },
                "font": {"color": "rgba(0,0,0,0)"},  # 50 step labels would overprint
                "ticklen": 3,
                "pad": {"t": 0},
            }
        ],
    )
    top = max((by for _, (_, by) in workspace_layout(scenario)), default=width) + 0.12
    fig.update_xaxes(title="Along the belt, x (m)", range=[-0.05, length + 0.05])
    fig.update_yaxes(title="Across, y (m)", range=[-0.05, top], showgrid=False, zeroline=False)
    fig = style(
        fig,
        "Belt snapshot",
        f"Parts on the belt at t = {t:.1f} s; press play for the next {seconds:.0f} s · "
        "dotted boxes: workspaces",
        height=430,
    )
    fig.update_layout(margin={"b": 110})
    return fig


def workspace_layout(
    scenario: dict[str, Any],
) -> list[tuple[tuple[float, float], tuple[float, float]]]:
    """((a, b), bin position) per robot from a scenario dict, as the twin lays them out."""
    robots = scenario.get("robots") or {}
    width = float((scenario.get("belt") or {}).get("width", 0.4))
    n = int(robots.get("count", 4))
    if robots.get("workspaces"):
        spaces = [(float(a), float(b)) for a, b in robots["workspaces"]]
    else:
        a = float(robots.get("first_workspace_start", 0.3))
        size, gap = (
            float(robots.get("workspace_length", 0.5)),
            float(robots.get("workspace_gap", 0)),
        )
        spaces = [(a + i * (size + gap), a + i * (size + gap) + size) for i in range(n)]
    offsets = {int(o["robot"]): o.get("bin_offset") for o in robots.get("overrides") or []}
    default = robots.get("bin_offset") or (0.0, 0.2)
    out = []
    for i, (a, b) in enumerate(spaces, start=1):
        dx, dy = offsets.get(i) or default
        out.append(((a, b), ((a + b) / 2 + float(dx), width + float(dy))))
    return out


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
        "Filled markers reach the target with the requested confidence · error bars: 95 % CI "
        "· best policy at each point",
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
