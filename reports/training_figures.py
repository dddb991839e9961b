"""Training figures: learning curves, rules chosen per robot, the modes compared.

Pure functions from a run's logs and evaluation tables to plotly figures.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import plotly.graph_objects as go
from plotly.subplots import make_subplots

from pnp_twin.reports.html import esc
from pnp_twin.reports.style import PALETTE, cap_percent, rgba, style
from pnp_twin.reports.training_load import TrainingRun

RULE_ORDER = ("FIFO", "LIFO", "SIRO", "SD", "LD", "SPT")
HDQN_COLOR, RULE_COLOR = PALETTE[0], "#8d99ae"


def ci_text(low: float, high: float, digits: int = 2, sign: bool = False) -> str:
    if not (math.isfinite(low) and math.isfinite(high)):
        return "–"
    f = f"{{:+.{digits}f}}" if sign else f"{{:.{digits}f}}"
    return f"[{f.format(low)}, {f.format(high)}]"


def rule_colors(rules: list[str]) -> dict[str, str]:
    """One stable colour per rule: the paper's rules first, then any others."""
    known = [r for r in RULE_ORDER if r in rules] + sorted(r for r in rules if r not in RULE_ORDER)
    return {
        r: PALETTE[RULE_ORDER.index(r) if r in RULE_ORDER else i % len(PALETTE)]
        for i, r in enumerate(known)
    }


def episode_rates(log: pd.DataFrame) -> pd.DataFrame:
    """One row per finished training episode count: the gripping rate log.csv carried when
    the count first reached it (rows before the first episode ended hold a running value)."""
    if "episode" not in log.columns:
        return log[["step", "gripping_rate"]]
    rows = log.drop_duplicates("episode", keep="first")
    finished = rows[rows["episode"] > 0]
    return finished if len(finished) else rows


def smooth(values: pd.Series, n: int) -> pd.Series:
    """A centred rolling mean over about a twentieth of the curve."""
    return values.rolling(max(1, n // 20), center=True, min_periods=1).mean()


def learning_figure(run: TrainingRun) -> go.Figure:
    """Reward per step (top) and gripping rate (bottom) against training steps: training
    episodes, validation on held-out seeds, and the best rule's validation figure."""
    log = run.log if run.log is not None else pd.DataFrame(columns=["step", "reward_per_step"])
    fig = make_subplots(
        rows=2,
        cols=1,
        shared_xaxes=True,
        vertical_spacing=0.09,
        row_heights=[0.42, 0.58],
        subplot_titles=["Reward per step", "Gripping rate"],
    )
    _reward_traces(fig, log)
    shown = _episode_traces(fig, log)
    if run.eval is not None:
        shown += _validation_traces(fig, run.eval, log)
    rollout = run.meta.get("targets") == "rollout"
    fig.update_yaxes(title="Reward / step", row=1, col=1)
    fig.update_yaxes(title="G (%)", ticksuffix=" %", row=2, col=1)
    fig.update_xaxes(title="Labelled decisions" if rollout else "Training steps", row=2, col=1)
    if shown:
        low, high = min(shown), max(shown)
        pad = max(0.5, 0.08 * (high - low))
        fig.update_yaxes(range=[max(0.0, low - pad), min(101.0, high + pad)], row=2, col=1)
    fig = style(fig, f"Learning curves: {run.mode}", _learning_subtitle(run), height=560, top=110)
    fig.update_layout(legend={"y": -0.12, "yanchor": "top", "x": 0, "xanchor": "left"})
    fig.update_layout(margin={"b": 100})
    return fig


def _reward_traces(fig: go.Figure, log: pd.DataFrame) -> None:
    """The logged reward per step and its rolling mean (top panel)."""
    fig.add_trace(
        go.Scatter(
            x=log["step"],
            y=log["reward_per_step"],
            mode="lines",
            name="Reward per step (logged)",
            line={"color": rgba(PALETTE[1], 0.35), "width": 1},
            hovertemplate="step %{x:,}<br>reward/step %{y:.3f}<extra></extra>",
        ),
        row=1,
        col=1,
    )
    fig.add_trace(
        go.Scatter(
            x=log["step"],
            y=smooth(log["reward_per_step"], len(log)),
            mode="lines",
            name="Reward per step (rolling mean)",
            line={"color": PALETTE[1], "width": 2.2},
            hoverinfo="skip",
        ),
        row=1,
        col=1,
    )


def _episode_traces(fig: go.Figure, log: pd.DataFrame) -> list[float]:
    """Each training episode's gripping rate (bottom panel); the values drawn."""
    if "gripping_rate" not in log.columns:
        return []
    ep = episode_rates(log)
    fig.add_trace(
        go.Scatter(
            x=ep["step"],
            y=ep["gripping_rate"],
            mode="markers",
            name="Training episode",
            marker={"color": rgba(PALETTE[2], 0.45), "size": 5},
            hovertemplate="step %{x:,}<br>episode G %{y:.1f} %<extra></extra>",
        ),
        row=2,
        col=1,
    )
    return list(ep["gripping_rate"].tolist())


def _validation_traces(fig: go.Figure, ev: pd.DataFrame, log: pd.DataFrame) -> list[float]:
    """Validation rounds, the best checkpoint and the best rule's line; the values drawn."""
    fig.add_trace(
        go.Scatter(
            x=ev["step"],
            y=ev["gripping_rate"],
            mode="lines+markers",
            name="Validation (HDQN, greedy)",
            line={"color": HDQN_COLOR, "width": 2.5},
            marker={"size": 7},
            hovertemplate="step %{x:,}<br>validation G %{y:.2f} %<extra></extra>",
        ),
        row=2,
        col=1,
    )
    shown = list(ev["gripping_rate"].tolist())
    best = ev.loc[ev["gripping_rate"].idxmax()]
    fig.add_trace(
        go.Scatter(
            x=[best["step"]],
            y=[best["gripping_rate"]],
            mode="markers",
            name="Best checkpoint",
            marker={"color": HDQN_COLOR, "size": 15, "symbol": "star"},
            hovertemplate="best checkpoint: step %{x:,}, G %{y:.2f} %<extra></extra>",
        ),
        row=2,
        col=1,
    )
    if "best_rule_gripping_rate" not in ev.columns:
        return shown
    ref = float(ev["best_rule_gripping_rate"].iloc[-1])
    name = str(ev["best_rule"].iloc[-1]) if "best_rule" in ev.columns else "best rule"
    x = [
        float(min(ev["step"].min(), log["step"].min() if len(log) else math.inf)),
        float(max(ev["step"].max(), log["step"].max() if len(log) else -math.inf)),
    ]
    fig.add_trace(
        go.Scatter(
            x=x,
            y=[ref, ref],
            mode="lines",
            name=f"{name}, best rule (validation)",
            line={"color": RULE_COLOR, "width": 2, "dash": "dash"},
            hovertemplate=f"{esc(name)}: G %{{y:.2f}} %<extra></extra>",
        ),
        row=2,
        col=1,
    )
    return [*shown, ref]


def _learning_subtitle(run: TrainingRun) -> str:
    """What was validated, how often, on how many seeds."""
    args = run.meta.get("train_args") or {}
    if not args:
        return run.label
    every = args.get("eval_every")
    if run.meta.get("targets") == "rollout":  # one validation per round of episodes
        cadence = f"after every {args.get('round_episodes', '?')} labelled episodes"
    else:
        cadence = f"every {every:,} steps" if isinstance(every, int) else "periodically"
    return f"{run.label} · validation {cadence} on {args.get('eval_seeds', '?')} held-out seeds"


def rule_shares(rules: pd.DataFrame) -> pd.DataFrame:
    """Share (%) of each robot's rule choices per rule, NooP decisions left out."""
    chosen = rules[rules["rule"].astype(str) != "NooP"].copy()
    chosen["rule"] = chosen["rule"].astype(str)
    total = chosen.groupby("robot")["count"].transform("sum")
    chosen["share"] = 100.0 * chosen["count"] / total.where(total > 0)
    return chosen


def rules_figure(runs: list[TrainingRun]) -> go.Figure:
    """The paper's figure 13: per robot, the share of decisions on which the HDQN chose
    each rule, one panel per run."""
    shown = [r for r in runs if r.rules is not None]
    fig = make_subplots(
        rows=1,
        cols=len(shown),
        shared_yaxes=True,
        horizontal_spacing=0.05,
        subplot_titles=[r.label for r in shown],
    )
    names = sorted({str(x) for r in shown for x in r.rules["rule"]} - {"NooP"})  # type: ignore[index]
    colors = rule_colors(names)
    order = [r for r in RULE_ORDER if r in names] + [r for r in names if r not in RULE_ORDER]
    for col, run in enumerate(shown, start=1):
        shares = rule_shares(run.rules)  # type: ignore[arg-type]
        robots = sorted(shares["robot"].unique().tolist())
        for rule in order:
            d = shares[shares["rule"] == rule].set_index("robot").reindex(robots)
            fig.add_trace(
                go.Bar(
                    x=[f"Robot {int(r)}" for r in robots],
                    y=d["share"].fillna(0.0),
                    name=rule,
                    legendgroup=rule,
                    showlegend=col == 1,
                    marker_color=colors[rule],
                    customdata=np.column_stack([d["count"].fillna(0).astype(int)]),
                    hovertemplate=f"%{{x}}: {rule} %{{y:.1f}} % "
                    "(%{customdata[0]} decisions)<extra></extra>",
                ),
                row=1,
                col=col,
            )
    fig.update_layout(barmode="stack")
    fig.update_yaxes(
        title="Share of decisions (%)", ticksuffix=" %", range=[0, 100.5], row=1, col=1
    )
    fig = style(
        fig,
        "Share of each rule in the HDQN's choices",
        "Greedy HDQN on one held-out seed · decisions with no part to pick (NooP) left out",
        height=430,
        top=110,
    )
    fig.update_layout(legend={"y": -0.12, "yanchor": "top", "x": 0, "xanchor": "left"})
    return fig


def modes_figure(rows: pd.DataFrame) -> go.Figure:
    """The paper's figure 18: held-out gripping rate of each mode's HDQN next to the best
    rule under the same termination scheme, with 95 % CIs (points, so that the axis need
    not start at zero for a gap of one point to show)."""
    x = [f"<b>{r.mode}</b><br>{r.termination}" for r in rows.itertuples()]
    fig = go.Figure()
    series = (
        (
            "HDQN",
            "hdqn",
            "hdqn_low",
            "hdqn_high",
            HDQN_COLOR,
            [f"HDQN ({m})" for m in rows["mode"]],
        ),
        (
            "Best rule, same termination",
            "rule_mean",
            "rule_low",
            "rule_high",
            RULE_COLOR,
            list(rows["rule"]),
        ),
    )
    for who, mean, low, high, color, names in series:
        fig.add_trace(
            go.Scatter(
                x=x,
                y=rows[mean],
                mode="markers",
                name=who,
                marker={
                    "color": color,
                    "size": 13,
                    "symbol": "circle" if who == "HDQN" else "diamond",
                },
                error_y={
                    "type": "data",
                    "array": (rows[high] - rows[mean]).fillna(0),
                    "arrayminus": (rows[mean] - rows[low]).fillna(0),
                    "thickness": 1.8,
                    "width": 6,
                    "color": color,
                },
                customdata=np.column_stack([rows["n"], names]),
                hovertemplate="%{customdata[1]}: G %{y:.2f} % on %{customdata[0]} "
                "seeds<extra></extra>",
            )
        )
    fig.update_layout(scattermode="group", scattergap=0.6)
    for label, r in zip(x, rows.itertuples(), strict=True):
        fig.add_annotation(
            x=label,
            y=1.0,
            yref="paper",
            yanchor="bottom",
            showarrow=False,
            text=f"HDQN {r.hdqn:.2f} % vs {esc(r.rule)} {r.rule_mean:.2f} %<br>"
            f"<span style='color:#5f6b7a'>paired Δ {r.diff:+.2f} "
            f"{ci_text(r.diff_low, r.diff_high, sign=True)}</span>",
            font={"size": 12},
        )
    lows = [*rows["hdqn_low"], *rows["rule_low"], *rows["hdqn"], *rows["rule_mean"]]
    highs = [*rows["hdqn_high"], *rows["rule_high"], *rows["hdqn"], *rows["rule_mean"]]
    cap_percent(fig, lows, highs)
    fig.update_xaxes(type="category")
    fig.update_yaxes(title="Gripping rate (%)", ticksuffix=" %")
    seeds = sorted(set(rows["n"]))
    subtitle = (
        f"{' / '.join(str(s) for s in seeds)} held-out seeds per run, paired (common random "
        "numbers) · error bars: 95 % CI"
    )
    fig = style(fig, "Held-out gripping rate per training set-up", subtitle, height=470, top=130)
    fig.update_layout(legend={"y": 1.2})
    return fig
