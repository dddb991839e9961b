"""The capacity report: one self-contained page from a ``pnp-twin capacity`` folder.

It reads ``DIR/capacity.json`` only (``pnp_twin.studies.capacity`` writes it; nothing is
simulated here): the answer first ("With 6 robots you can promise ... parts/s"), then the
curve of G against part flow with its confidence band, the target and the three crossings
(the flow met with confidence, the mean's, the upper bound's), and every evaluated flow.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import plotly.graph_objects as go

from pnp_twin.reports.html import Page, Section, esc, render, table_html
from pnp_twin.reports.load import ReportError, read_json
from pnp_twin.reports.style import PALETTE, cap_percent, rgba, style
from pnp_twin.reports.text import fmt_pct
from pnp_twin.twin.output import write_text

SUMMARY_FILE = "capacity.json"
REPORT_FILE = "report.html"


def load_capacity(folder: Path | str) -> dict[str, Any]:
    """capacity.json of ``folder``, or a one-line ReportError."""
    path = Path(folder) / SUMMARY_FILE
    if not path.is_file():
        raise ReportError(f"{folder}: no {SUMMARY_FILE}; run `pnp-twin capacity` first")
    return read_json(path)


def capacity_figure(c: dict[str, Any]) -> go.Figure:
    """G against part flow (best rule at each flow) with the CI band, the target and the
    crossings."""
    curve = c.get("curve") or []
    xs = [p["rate"] for p in curve]
    lows, highs = [p["low"] for p in curve], [p["high"] for p in curve]
    fig = go.Figure()
    level = 100 * float(c.get("confidence") or 0.95)
    fig.add_scatter(
        x=xs + xs[::-1],
        y=highs + lows[::-1],
        fill="toself",
        mode="none",
        fillcolor=rgba(PALETTE[0], 0.15),
        name=f"{level:g} % CI",
        hoverinfo="skip",
    )
    fig.add_scatter(
        x=xs,
        y=[p["mean"] for p in curve],
        mode="lines+markers",
        name="mean G (best rule)",
        line={"color": PALETTE[0]},
        customdata=[[p["policy"]] for p in curve],
        hovertemplate="%{x:.3g} parts/s: G = %{y:.1f} % (%{customdata[0]})<extra></extra>",
    )
    target = float(c["target"])
    fig.add_hline(
        y=target,
        line={"color": "#c0392b", "dash": "dash"},
        annotation_text=f"target {fmt_pct(target)}",
        annotation_position="bottom left",
    )
    for key, label, dash in (("ci_low", "promise", "solid"), ("max_rate", "mean", "dot")):
        x = c.get(key)
        if x is not None:
            fig.add_vline(
                x=x,
                line={"color": "#2a9d8f", "width": 1.5, "dash": dash},
                annotation_text=f"{label}: {x:.3g}",
                annotation_position="top right",
            )
    fig.update_xaxes(title="Part flow (parts/s)")
    fig.update_yaxes(title="Gripping rate (%)", ticksuffix=" %")
    cap_percent(fig, [*lows, target], [*highs, target])
    return style(
        fig,
        "Gripping rate against part flow",
        f"best rule at each flow · band: {level:g} % CI after picking the rule (Bonferroni) · "
        "every flow the root finding evaluated, same seeds at each",
        height=440,
    )


def flows_table(c: dict[str, Any]) -> str:
    """Every evaluated flow: the best rule, G and its interval."""
    rows = [
        [
            f"{p['rate']:.4g}",
            esc(p["policy"]),
            fmt_pct(p["mean"]),
            f"{p['low']:.1f} to {p['high']:.1f} %",
            "yes" if p["low"] >= c["target"] else "no",
        ]
        for p in c.get("curve") or []
    ]
    header = ["Part flow (parts/s)", "Best rule", "Mean G", "CI of G", "Promised"]
    return table_html(header, rows, scroll=len(rows) > 14)


def build_capacity_page(c: dict[str, Any]) -> Page:
    """The capacity report as a Page."""
    conf = 100 * float(c.get("confidence") or 0.95)
    answer = f'<div class="answer"><p>{esc(c["text"])}</p>'
    answer += (
        "<p>"
        + esc(
            f"Flows are found by root finding (doubling or halving from the scenario's flow, "
            f"then bisection to {100 * float(c.get('tolerance') or 0.01):g} %), not a grid; "
            f"{c['evaluated']} flows evaluated with {c['replications']} replications each "
            f"and common random numbers."
        )
        + "</p></div>"
    )
    lo, hi, mid = c.get("ci_low"), c.get("ci_high"), c.get("max_rate")
    cards = [
        (
            "Promise",
            "–" if lo is None else f"{lo:.3g} parts/s",
            f"G ≥ {c['target']:g} % at {conf:g} %",
        ),
        ("Mean crossing", "–" if mid is None else f"{mid:.3g} parts/s", "mean G = target"),
        ("Upper crossing", "–" if hi is None else f"{hi:.3g} parts/s", "beyond: surely missed"),
        ("Robots", str(c.get("robots")), ", ".join(c.get("rules") or [])),
    ]
    facts = [
        ("Scenario", esc(str(c.get("scenario_name") or ""))),
        ("Rules", esc(", ".join(c.get("rules") or []))),
        (
            "Runs",
            esc(
                f"{c['replications']} replications per flow, {c.get('duration', 0):g} s each "
                f"({c.get('warmup', 0):g} s warm-up); {c['simulated']} flows simulated, "
                f"{c['replayed']} replayed from evals/"
            ),
        ),
        ("Command", f"<code>{esc(c.get('command') or '')}</code>"),
    ]
    body = "".join(f"<tr><th>{k}</th><td>{v}</td></tr>" for k, v in facts)
    sections = [
        Section("answer", "The answer", "", [answer, capacity_figure(c)]),
        Section(
            "setup", "What was run", "", [f'<table class="facts"><tbody>{body}</tbody></table>']
        ),
        Section("flows", "Every flow evaluated", "", [flows_table(c)]),
    ]
    lead = esc(str((c.get("scenario") or {}).get("description") or ""))
    return Page(
        title=f"{c.get('scenario_name')}: capacity",
        eyebrow="pnp-twin report<span class='badge'>capacity</span>",
        lead=lead,
        cards=cards,
        sections=sections,
        footer=esc("Generated by pnp-twin from capacity.json · self-contained: opens offline."),
    )


def build_capacity_report(folder: Path | str, out: Path | str | None = None) -> Path:
    """Write ``folder``/report.html (or ``out``) from capacity.json; returns the path."""
    c = load_capacity(folder)
    target = Path(out) if out is not None else Path(folder) / REPORT_FILE
    if not math.isfinite(float(c.get("target") or math.nan)):
        c["target"] = math.nan
    return write_text(render(build_capacity_page(c)), target)
