"""Figures from one run's records: robot shares, activity timeline, belt snapshot.

Pure functions from the records tables to plotly figures: no files, no simulation.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd
import plotly.graph_objects as go
from plotly.subplots import make_subplots
from pydantic import ValidationError

from pnp_twin.reports.style import (
    PALETTE,
    PART_COLORS,
    STATE_COLORS,
    STATE_LABELS,
    rgba,
    style,
)
from pnp_twin.reports.text import (
    at_point,
    point_label,
)
from pnp_twin.twin.decision import RobotSpec
from pnp_twin.twin.plan import robot_specs
from pnp_twin.twin.scenario import Scenario


def robot_count(results: pd.DataFrame) -> int:
    """Number of robots from the r{i}_utilisation columns that hold a value in these rows
    (a study over robot counts has r5_... columns, empty in its 4-robot rows)."""
    n = 0
    while f"r{n + 1}_utilisation" in results.columns:
        if not results[f"r{n + 1}_utilisation"].notna().any():
            break
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
        subplot_titles=["Time share per robot", "Parts each robot left: passed on or lost"],
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
    passed = [float(runs[f"r{i}_passed_on"].mean()) for i in range(1, n + 1)]
    lost = [float(runs[f"r{i}_lost"].mean()) for i in range(1, n + 1)]
    picks = [float(runs[f"r{i}_picks"].mean()) for i in range(1, n + 1)]
    for label, values, color in (
        ("Passed on (picked downstream)", passed, "#e9a03b"),
        ("Lost (return conveyor)", lost, "#c0392b"),
    ):
        fig.add_trace(
            go.Bar(
                x=names,
                y=values,
                name=label,
                marker_color=color,
                customdata=np.column_stack([picks]),
                hovertemplate="%{x}: %{y:.1f} parts "
                + label.split(" (")[0].lower()
                + ", %{customdata[0]:.0f} picked<extra></extra>",
            ),
            row=1,
            col=2,
        )
    passed = [a + b for a, b in zip(passed, lost, strict=True)]
    fig.update_layout(barmode="stack")
    fig.update_yaxes(title="Share of the window (%)", ticksuffix=" %", range=[0, 101], row=1, col=1)
    fig.update_yaxes(title="Parts per run", rangemode="tozero", row=1, col=2)
    fig.update_yaxes(range=[0, max(passed, default=1) * 1.18 + 1], row=1, col=2)
    reps = len(runs)
    where = point_label(point, list(point)) if point else "the baseline"
    subtitle = f"{policy} at {where} · mean of {reps} replication{'s' if reps != 1 else ''}"
    fig = style(fig, "Robots: utilisation, parts passed on and lost", subtitle, height=450, top=110)
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
                y=[names[i - 1] for i in s["robot"]],  # the records number robots from 1
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


BY_DESIGN = "passed on by design"  # the belt category of a kind no robot picks


def belt_positions(
    parts: pd.DataFrame, belt_speed: float, t: float, untargeted: Sequence[str] = ()
) -> dict[str, pd.DataFrame]:
    """Parts on the belt at instant ``t`` (fed, not yet gripped or gone), by category, with
    their position x = v_b (t - fed_at); with ``untargeted`` kinds (no robot picks them)
    their parts are a fourth category, passed on by design, not "will be missed"."""
    on = parts[(parts["fed_at"] <= t) & (parts["left_at"] > t)].copy()
    on["x"] = belt_speed * (t - on["fed_at"])
    picked = on["outcome"] == "picked"
    claimed = picked & (on["decided_at"] <= t)
    if not untargeted:
        return {
            "to be picked": on[picked & ~claimed],
            "claimed": on[claimed],
            "will be missed": on[~picked],
        }
    design = on["kind"].isin(list(untargeted))
    return {
        "to be picked": on[picked & ~claimed],
        "claimed": on[claimed],
        "will be missed": on[~picked & ~design],
        BY_DESIGN: on[~picked & design],
    }


def belt_traces(
    parts: pd.DataFrame,
    belt_speed: float,
    t: float,
    untargeted: Sequence[str] = (),
    kinds: bool = False,
) -> list[go.Scatter]:
    """The part markers traces of one instant (always the same ones, maybe empty: three,
    four with ``untargeted`` kinds); ``kinds``: hovering a part names its kind."""
    out = []
    for cat, d in belt_positions(parts, belt_speed, t, untargeted).items():
        robot = d["robot"].astype("Float64").fillna(0).astype(int)  # from 1; 0: none
        data = [d["part"], robot] + ([d["kind"]] if kinds else [])
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
                customdata=np.column_stack(data),
                hovertemplate="part %{customdata[0]}"
                + (" (%{customdata[2]})" if kinds else "")
                + "<br>x = %{x:.2f} m, y = %{y:.2f} m"
                + ("<br>robot %{customdata[1]}" if cat in ("to be picked", "claimed") else "")
                + "<extra>"
                + cat
                + "</extra>",
            )
        )
    return out


@dataclass(frozen=True)
class Animation:
    """Which stretch of a recorded run the belt animation covers: from ``start`` s (None:
    the end of the warm-up) for ``seconds`` s, a frame every ``step`` s."""

    start: float | None = None
    seconds: float = 60.0
    step: float = 0.2

    def window(self, warmup: float, duration: float) -> tuple[float, float]:
        """(t0, seconds) inside the recorded run [0, duration)."""
        t0 = warmup if self.start is None else self.start
        t0 = min(max(t0, 0.0), max(duration - self.step, 0.0))
        return t0, max(min(self.seconds, duration - t0), self.step)


def animated_belt(
    parts: pd.DataFrame,
    scenario: dict[str, Any],
    animation: Animation,
    warmup: float,
    duration: float,
) -> go.Figure:
    """The belt figure over the chosen window of the run."""
    t0, seconds = animation.window(warmup, duration)
    return belt_figure(parts, scenario, t0, seconds, animation.step)


def belt_figure(
    parts: pd.DataFrame,
    scenario: dict[str, Any],
    t: float,
    seconds: float = 5.0,
    step: float = 0.1,
) -> go.Figure:
    """The line seen from above at instant ``t``: the belt, each robot's workspace, side,
    base, reach and bin (:func:`twin.plan.robot_specs`), and the parts on the belt coloured
    by what happens to them; a play button and slider animate the next ``seconds``."""
    line = recorded_scenario(scenario)
    belt, specs = line.belt, line_specs(line)
    untargeted = untargeted_kinds(line.kind_names(), specs)
    kinds = bool(line.feeder.kinds) and "kind" in parts.columns
    untargeted = untargeted if kinds else []

    def traces(ti: float) -> list[go.Scatter]:
        return belt_traces(parts, belt.speed, ti, untargeted, kinds)

    fig = go.Figure(data=traces(t))
    times = np.round(np.arange(t, t + seconds + 1e-9, step), 6)
    fig.frames = [go.Frame(data=traces(float(ti)), name=f"{ti:.1f}") for ti in times]
    fig.update_layout(
        shapes=belt_shapes(belt.length, belt.width, specs),
        annotations=robot_labels(specs, line.kind_names()),
        updatemenus=[play_buttons(step)],
        sliders=[time_slider(times)],
    )
    low, top = y_range(belt.width, specs)
    fig.update_xaxes(title="Along the belt, x (m)", range=[-0.05, belt.length + 0.05])
    fig.update_yaxes(title="Across, y (m)", range=[low, top], showgrid=False, zeroline=False)
    what = "dotted boxes: workspaces"
    if shaped(specs):
        what += ", bars: each robot's side, dots: bases"
        what += ", circles: reach" if any(s.reach > 0 for s in specs) else ""
    height = max(430, round(250 + 160 * (top - low))) if shaped(specs) else 430
    if any(s.reach > 0 for s in specs):  # metres alike both ways: a reach circle is round
        fig.update_yaxes(scaleanchor="x", scaleratio=1)
        span = belt.length + 0.1
        height = min(MAX_HEIGHT, max(430, round(210 + PLOT_WIDTH * (top - low) / span)))
    fig = style(
        fig,
        "Belt snapshot",
        f"Parts on the belt at t = {t:.1f} s; press play for the next {seconds:.0f} s · {what}",
        height=height,
    )
    fig.update_layout(margin={"b": 110})
    return fig


BIN_HALF = 0.045  # m, half the side of a bin's square in the belt figure
LABEL_GAP = 0.04  # m between a bin and its label
BASE_PX = 6  # px, radius of a robot's base marker
PLOT_WIDTH = 960  # px, about the plot area's width on a screen (sizes an equal-aspect figure)
MAX_HEIGHT = 820  # px: a taller line is drawn with a wider x range instead


def y_range(width: float, specs: list[RobotSpec]) -> tuple[float, float]:
    """The belt figure's y range: the belt, every base and every bin with its label (a
    reach circle may be clipped); a one-sided line's as it always was."""
    ys = [y for s in specs for y in (s.bin[1], s.mount[1])]
    low = min([0.0, *ys])
    top = max([width, *ys])
    if not shaped(specs):
        return -0.05, top + 0.12
    low = low - BIN_HALF - LABEL_GAP - 0.08 if low < 0 else -0.05
    return low, top + BIN_HALF + LABEL_GAP + 0.07


def shaped(specs: list[RobotSpec]) -> bool:
    """Whether the line has robots off the upper side or with a reach: then the belt figure
    draws each robot's side bar and base (and reach circle)."""
    return any(s.side != "upper" or s.reach > 0 for s in specs)


def side_y(spec: RobotSpec) -> float:
    """Where a robot's side bar runs: the belt edge it stands at, or the belt's centre line
    for a robot over the belt."""
    if spec.side == "lower":
        return 0.0
    if spec.side == "over":
        return spec.belt_width / 2.0
    return spec.belt_width


def belt_shapes(length: float, width: float, specs: list[RobotSpec]) -> list[dict[str, Any]]:
    """The belt, and per robot its workspace (dotted), its bin, and (on a line with robots
    on several sides or with a reach) a bar along its side, its base and its reach circle,
    as plotly layout shapes named after what they draw ("bin R2", "reach R2", ...)."""
    shapes: list[dict[str, Any]] = [
        {
            "type": "rect",
            "name": "belt",
            "x0": 0,
            "x1": length,
            "y0": 0,
            "y1": width,
            "fillcolor": "#eef1f5",
            "line": {"color": "#9aa5b1", "width": 1},
            "layer": "below",
        }
    ]
    drawn = shaped(specs)
    for spec in specs:
        color = PALETTE[spec.index % len(PALETTE)]
        tag = f"R{spec.index + 1}"
        (a, b), (bx, by), (mx, my) = spec.workspace, spec.bin, spec.mount
        shapes.append(
            {
                "type": "rect",
                "name": f"workspace {tag}",
                "x0": a,
                "x1": b,
                "y0": 0,
                "y1": width,
                "fillcolor": rgba(color, 0.07),
                "line": {"color": rgba(color, 0.8), "width": 1.5, "dash": "dot"},
                "layer": "below",
            }
        )
        if drawn:
            y = side_y(spec)
            shapes.append(
                {
                    "type": "line",
                    "name": f"side {tag}",
                    "x0": a,
                    "x1": b,
                    "y0": y,
                    "y1": y,
                    "line": {
                        "color": rgba(color, 0.45 if spec.side == "over" else 0.9),
                        "width": 5,
                    },
                    "layer": "below",
                }
            )
        if spec.reach > 0:
            r = spec.reach
            shapes.append(
                {
                    "type": "circle",
                    "name": f"reach {tag}",
                    "x0": mx - r,
                    "x1": mx + r,
                    "y0": my - r,
                    "y1": my + r,
                    "line": {"color": rgba(color, 0.7), "width": 1.2, "dash": "dash"},
                    "layer": "below",
                }
            )
        if drawn:
            shapes.append(
                {
                    "type": "circle",
                    "name": f"base {tag}",
                    "xsizemode": "pixel",
                    "ysizemode": "pixel",
                    "xanchor": mx,
                    "yanchor": my,
                    "x0": -BASE_PX,
                    "x1": BASE_PX,
                    "y0": -BASE_PX,
                    "y1": BASE_PX,
                    "fillcolor": color,
                    "line": {"color": "white", "width": 1.5},
                }
            )
        shapes.append(
            {
                "type": "rect",
                "name": f"bin {tag}",
                "x0": bx - BIN_HALF,
                "x1": bx + BIN_HALF,
                "y0": by - BIN_HALF,
                "y1": by + BIN_HALF,
                "fillcolor": rgba(color, 0.25),
                "line": {"color": color, "width": 1},
            }
        )
    return shapes


def robot_labels(specs: list[RobotSpec], kinds: tuple[str, ...] = ("",)) -> list[dict[str, Any]]:
    """'R2 bin' beside each bin (outward: above an upper bin, below a lower one) and, where
    bases are drawn, 'R2' beside each base; hover one for the robot's side, reach and kinds."""
    drawn = shaped(specs)
    out: list[dict[str, Any]] = []
    for spec in specs:
        i = spec.index + 1
        (a, b), (bx, by), (mx, my) = spec.workspace, spec.bin, spec.mount
        picks = [k for k, p in zip(kinds, spec.picks, strict=False) if p and k]
        info = f"robot {i}, {spec.side} side<br>workspace x = {a:g} to {b:g} m"
        info += f"<br>base ({mx:.2f}, {my:.2f}) m"
        info += f", reach {spec.reach:g} m" if spec.reach > 0 else ", no reach limit"
        info += f"<br>bin ({bx:.2f}, {by:.2f}) m"
        if picks and len(picks) < len([k for k in kinds if k]):
            info += "<br>picks " + ", ".join(picks)
        below = by < 0
        out.append(
            {
                "x": bx,
                "y": by - BIN_HALF - LABEL_GAP if below else by + BIN_HALF + LABEL_GAP,
                "text": f"<b>R{i}</b> bin",
                "showarrow": False,
                "hovertext": info,
                "name": f"bin R{i}",
            }
        )
        if drawn:
            out.append(
                {
                    "x": mx,
                    "y": my,
                    "xshift": BASE_PX + 4,
                    "xanchor": "left",
                    "text": f"<b>R{i}</b>",
                    "showarrow": False,
                    "font": {"size": 11, "color": PALETTE[spec.index % len(PALETTE)]},
                    "hovertext": info,
                    "name": f"base R{i}",
                }
            )
    return out


def play_buttons(step: float) -> dict[str, Any]:
    """The play / pause buttons of the belt animation (one frame per ``step`` seconds)."""
    play = {"frame": {"duration": int(step * 1000), "redraw": False}, "fromcurrent": True}
    play["transition"] = {"duration": 0}
    return {
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


def time_slider(times: np.ndarray) -> dict[str, Any]:
    """The slider over the animation's frames, one step per instant of ``times``."""
    steps = [
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
    return {
        "steps": steps,
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


def recorded_scenario(scenario: dict[str, Any]) -> Scenario:
    """The scenario a run recorded (its ``model_dump``), validated again; a record that no
    longer validates falls back to its belt and robots sections (defaults for the rest)."""
    try:
        return Scenario.model_validate(scenario)
    except ValidationError:
        sections = {k: scenario[k] for k in ("belt", "robots") if k in scenario}
        return Scenario.model_validate(sections)


def untargeted_kinds(names: Sequence[str], specs: list[RobotSpec]) -> list[str]:
    """The kinds of part no robot picks (passed on by design); [] on a line of one kind."""
    return [
        name
        for c, name in enumerate(names)
        if name and not any(not s.picks or s.picks[c] for s in specs)
    ]


def line_specs(scenario: Scenario | dict[str, Any]) -> list[RobotSpec]:
    """Each robot's geometry (workspace, side, base, reach, bin) as the twin lays it out:
    :func:`twin.plan.robot_specs`, never re-derived here."""
    if isinstance(scenario, dict):
        scenario = recorded_scenario(scenario)
    return robot_specs(scenario)
