"""The design report: one self-contained page from a ``pnp-twin design`` folder.

It reads ``DIR/design.json`` only (``pnp_twin.studies.design`` writes it; nothing is
simulated here): the answer first (the cheapest configuration meeting the target, its G
with the interval that holds after the selection, its total cost, and the next best), then
the cost-against-G front, the configurations that meet the target with their lost-parts
cost, and every configuration with the replications the sequential procedure gave it.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import plotly.graph_objects as go

from pnp_twin.reports.html import Page, Section, esc, render, table_html
from pnp_twin.reports.load import ReportError, read_json
from pnp_twin.reports.style import PALETTE, style
from pnp_twin.reports.text import fmt_bound, fmt_pct, param_label, param_value
from pnp_twin.reports.whatif import whatif_html
from pnp_twin.twin.output import write_text

SUMMARY_FILE = "design.json"
REPORT_FILE = "report.html"
STATES = {"met": ("meets the target", PALETTE[2]), "open": ("undecided", "#9aa5b1")}
STATES["missed"] = ("misses the target", PALETTE[3])


def load_design(folder: Path | str) -> dict[str, Any]:
    """design.json of ``folder``, or a one-line ReportError."""
    path = Path(folder) / SUMMARY_FILE
    if not path.is_file():
        raise ReportError(f"{folder}: no {SUMMARY_FILE}; run `pnp-twin design` first")
    return read_json(path)


def payback_card(d: dict[str, Any]) -> list[tuple[str, str, str]]:
    """The payback against today's line, where a baseline was given."""
    p = d.get("payback")
    if not p:
        return []
    if p["payback_months"] is None:
        return [("Payback", "none", "saves nothing in lost parts against today's line")]
    late = p["payback_months_high"]
    span = f"{p['payback_months_low']:.1f} to " + (f"{late:.1f}" if late is not None else "never")
    return [
        (
            "Payback",
            f"{p['payback_months']:.1f} months",
            f"[{span}] · saves {p['saving_per_year']:,.0f} a year",
        )
    ]


def choice_label(choice: dict[str, Any], notes: Any = ()) -> str:
    """'6 robots · arm speed 4 m/s · SPT' (and the line's notes: 'robot 4 arm speed 1.5
    m/s', robots owned)."""
    words = []
    for path, value in choice.items():
        if path == "policy":
            continue
        if path == "robots.count":
            words.append(f"{value} robots")
        else:
            words.append(param_value(path, value, lower=True))
    return " · ".join([*words, *notes, str(choice.get("policy"))])


def front_figure(d: dict[str, Any]) -> go.Figure:
    """Total cost against G for every configuration, coloured by the decision."""
    fig = go.Figure()
    for state, (name, color) in STATES.items():
        rows = [r for r in d["rows"] if r["state"] == state]
        if not rows:
            continue
        fig.add_scatter(
            x=[r["total_cost"] for r in rows],
            y=[r["gripping_rate"] for r in rows],
            mode="markers",
            name=name,
            marker={"color": color, "size": 10},
            error_y={
                "type": "data",
                "array": [r["ci_high"] - r["gripping_rate"] for r in rows],
                "arrayminus": [r["gripping_rate"] - r["ci_low"] for r in rows],
                "thickness": 1,
                "color": color,
            },
            text=[choice_label(r["choice"]) for r in rows],
            hovertemplate="%{text}<br>G = %{y:.1f} %<br>total cost %{x:,.0f}<extra></extra>",
        )
    if d.get("choice") is not None:
        fig.add_scatter(
            x=[d["total_cost"]],
            y=[d["gripping_rate"]],
            mode="markers+text",
            name="the answer",
            marker={"symbol": "star", "size": 18, "color": "#e9c46a", "line": {"width": 1}},
            text=["answer"],
            textposition="bottom right",
        )
    fig.add_hline(
        y=float(d["target"]),
        line={"color": "#c0392b", "dash": "dash"},
        annotation_text=f"target {fmt_pct(float(d['target']))}",
        annotation_position="bottom right",
    )
    fig.update_xaxes(title="Total cost of ownership (capital + lost parts)")
    fig.update_yaxes(title="Gripping rate (%)", ticksuffix=" %")
    level = 100 * float(d["confidence"])
    return style(
        fig,
        "Cost against gripping rate",
        f"every configuration · error bars: the interval that holds for all of them together "
        f"({level:g} %, {bonferroni_text(d)})",
        height=460,
    )


def bonferroni_text(d: dict[str, Any]) -> str:
    """'Bonferroni over 24 configurations × 4 looks = 96' (× conditions where there are)."""
    k, n_looks = int(d["configurations"]), d.get("looks")
    if n_looks is None:  # a folder from before design.json kept its looks: from the level
        n_looks = round((1 - float(d["confidence"])) / (1 - float(d["confidence_each"])) / k)
    parts = [f"{k} configurations", f"{n_looks} looks"]
    conditions = len(d.get("conditions") or [])
    if conditions > 1:
        parts.append(f"{conditions} conditions")
    total = k * int(n_looks) * max(1, conditions)
    return f"Bonferroni over {' × '.join(parts)} = {total}"


def interval_text(r: dict[str, Any], target: float) -> str:
    """'94.99 to 96.2 %': bounds with the decimals it takes not to round across the target."""
    return f"{fmt_bound(r['ci_low'], target)} to {fmt_bound(r['ci_high'], target)} %"


def met_table(d: dict[str, Any]) -> str:
    """The configurations that meet the target, cheapest first, with the lost-parts cost."""
    paths = list(d.get("vary") or {})
    header = [param_label(p) for p in paths] + ["Rule", "Gripping rate", "Interval"]
    header += ["Replications", "Capital", "Lost parts", "Total cost"]
    rows: list[list[str]] = []
    classes: list[str] = []
    for r in d["rows"]:
        if r["state"] != "met":
            continue
        c = r["choice"]
        rows.append(
            [esc(c.get(p)) for p in paths]
            + [
                esc(c.get("policy")),
                fmt_pct(r["gripping_rate"]),
                interval_text(r, float(d["target"])),
                str(r["replications"]),
                f"{r['capital_cost']:,.0f}",
                f"{r['lost_parts_cost']:,.0f}",
                f"{r['total_cost']:,.0f}",
            ]
        )
        classes.append("best" if not classes else "")
    return table_html(header, rows, left=len(paths) + 1, classes=classes, scroll=len(rows) > 14)


def all_table(d: dict[str, Any]) -> str:
    """Every configuration, cheapest first (the order design.json keeps), with its total
    cost, its decision and the replications it got."""
    paths = list(d.get("vary") or {})
    header = [param_label(p) for p in paths] + ["Rule", "Gripping rate", "Interval"]
    header += ["Replications", "Decision", "Total cost"]
    rows = [
        [esc(r["choice"].get(p)) for p in paths]
        + [
            esc(r["choice"].get("policy")),
            fmt_pct(r["gripping_rate"]),
            interval_text(r, float(d["target"])),
            str(r["replications"]),
            STATES[r["state"]][0],
            f"{r['total_cost']:,.0f}",
        ]
        for r in d["rows"]
    ]
    return table_html(header, rows, left=len(paths) + 1, scroll=len(rows) > 14)


def bill_table(d: dict[str, Any]) -> str:
    """The answer's bill: each robot's arm speed and price (owned ones at 0), the belt and the
    running cost; empty without a cost file or an answer."""
    chosen, prices = d.get("scenario_chosen"), d.get("robot_prices")
    if not d.get("cost_file") or not chosen or prices is None:
        return ""
    robots = chosen["robots"]
    speed = {
        o["robot"]: o["arm_speed"] for o in robots.get("overrides") or [] if o.get("arm_speed")
    }
    owned = set((d.get("costs") or {}).get("owned") or ())
    rows = [
        [
            f"Robot {i}",
            f"{float(speed.get(i, robots['arm_speed'])):g} m/s",
            "owned" if i in owned else f"{p:,.0f}",
        ]
        for i, p in enumerate(prices, start=1)
    ]
    belt = d["capital_cost"] - sum(prices)
    rows.append(["Belt", f"{float(chosen['belt']['speed']):g} m/s", f"{belt:,.0f}"])
    rows.append(["Capital", "", f"{d['capital_cost']:,.0f}"])
    hours = float(d["costs"]["hours"])
    rows.append(
        [
            f"Running: lost parts over {hours:,.0f} h",
            "",
            f"{d['running_cost']:,.0f} [{d['total_cost_low'] - d['capital_cost']:,.0f}, "
            f"{d['total_cost_high'] - d['capital_cost']:,.0f}]",
        ]
    )
    return table_html(["Item", "Speed", "Price"], rows, left=2)


def build_design_page(d: dict[str, Any]) -> Page:
    """The design report as a Page."""
    reached = d.get("replications_reached") or sorted(set(d["rounds"]))
    how = (
        f"Sequential: {d['rounds'][0]} replications everywhere, then doubled only where a "
        f"configuration was still undecided and could be cheaper than the best one met "
        f"(configurations ended with {', '.join(map(str, reached))} replications): "
        f"{d['runs']} runs instead of {d['runs_fixed']}; common random numbers throughout."
    )
    conditions = d.get("conditions") or []
    if len(conditions) > 1:
        how += (
            f" Each configuration ran at each of {len(conditions)} conditions ("
            + "; ".join(
                ", ".join(f"{param_value(k, v, True)}" for k, v in c.items()) for c in conditions
            )
            + "): it meets the target only if it meets it at every one, and the G shown is the "
            "worst condition's; the lost parts are averaged over the conditions, weighted equally."
        )
    if d.get("continuous"):
        how += (
            f" {', '.join(param_label(p) for p in d['continuous'])}: a continuous range "
            f"searched by optuna's constrained TPE, {d['trials']} points per combination of "
            f"the other fields and rules ({d['evaluated']} distinct points evaluated; the "
            f"Bonferroni level counts all {d['configurations']} allowed)."
        )
    answer = f'<div class="answer"><p>{esc(d["text"])}</p><p>{esc(how)}</p></div>'
    costs = d.get("costs") or {}

    def price(v: Any, unit: str) -> str:
        if isinstance(v, dict):
            return ", ".join(f"{p:,.0f} at {s} {unit}" for s, p in v.items())
        return f"{float(v):,.0f}" if v is not None else "–"

    cost_text = (
        f"robot price {price(costs.get('robot_price'), 'm/s')}; belt price "
        f"{price(costs.get('belt_price'), 'm/s')}; {costs.get('lost_part_cost')} per lost part "
        f"over {costs.get('hours'):g} h"
    )
    choice = d.get("choice")
    cards = [
        (
            "Buy",
            "none meets it" if choice is None else choice_label(choice, d.get("notes") or ()),
            f"G ≥ {d['target']:g} % at {100 * d['confidence']:g} %",
        ),
        (
            "Promise",
            "–" if choice is None else f"G ≥ {fmt_bound(d['ci_low'], float(d['target']))} %",
            "lower bound after the selection",
        ),
        (
            "Total cost",
            "–" if choice is None else f"{d['total_cost']:,.0f}",
            "capital + lost parts"
            if choice is None or "total_cost_low" not in d
            else f"[{d['total_cost_low']:,.0f}, {d['total_cost_high']:,.0f}] · capital "
            f"{d['capital_cost']:,.0f} + running {d['running_cost']:,.0f}",
        ),
        *payback_card(d),
        ("Configurations", str(d["configurations"]), f"{d['runs']} runs"),
    ]
    paths = list(d.get("vary") or {})
    level = f"{100 * float(d['confidence']):g} %"
    rows = [
        {
            "values": {p: r["choice"].get(p) for p in paths},
            "policy": r["choice"].get("policy"),
            "mean": r["gripping_rate"],
            "low": r["ci_low"],
            "high": r["ci_high"],
            "cost": r["total_cost"],
            "note": {"met": "meets the target", "missed": "misses it"}.get(r["state"], "open"),
        }
        for r in d["rows"]
    ]
    start = dict(choice) if choice is not None else None
    panel = whatif_html(paths, rows, f"{level} simultaneous", start, target=float(d["target"]))
    sections = [
        Section("answer", "The answer", "", [answer, front_figure(d)]),
        Section(
            "whatif",
            "What if",
            esc("Choose a configuration: its gripping rate, interval and total cost."),
            [panel],
        ),
        Section(
            "met",
            "Configurations that meet the target",
            esc(f"Cheapest first; costs: {cost_text}."),
            [met_table(d)],
        ),
        Section("all", "Every configuration", "", [all_table(d)]),
    ]
    bill = bill_table(d)
    if bill:
        sections.insert(
            1,
            Section(
                "bill",
                "What it costs",
                esc(
                    "The answer's robots, each priced at its own arm speed, the belt, and the "
                    "running cost with its interval (lost parts are estimated from the runs)."
                ),
                [bill],
            ),
        )
    return Page(
        title=f"{d.get('scenario_name')}: design",
        eyebrow="pnp-twin report<span class='badge'>design</span>",
        lead=esc(str((d.get("scenario") or {}).get("description") or "")),
        cards=cards,
        sections=sections,
        footer=esc("Generated by pnp-twin from design.json · self-contained: opens offline."),
    )


def build_design_report(folder: Path | str, out: Path | str | None = None) -> Path:
    """Write ``folder``/report.html (or ``out``) from design.json; returns the path."""
    d = load_design(folder)
    target = Path(out) if out is not None else Path(folder) / REPORT_FILE
    return write_text(render(build_design_page(d)), target)
