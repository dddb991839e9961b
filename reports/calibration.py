"""The calibration report: one self-contained HTML page from a ``pnp-twin calibrate`` folder.

It reads ``DIR/calibration.json`` only (``pnp_twin.studies.calibrate_output`` writes it; no
simulation here) and shows, answer first: how close the fitted twin comes to the measured
points, measured against predicted per point with confidence intervals, the fitted response
across each varied field, and how well each parameter is determined (the objective's profile
along each parameter, and over each pair, where a diagonal valley means the two trade off
and the data cannot fit both).
"""

from __future__ import annotations

import json
import logging
import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import plotly.graph_objects as go
from plotly.subplots import make_subplots
from pydantic import BaseModel

from pnp_twin.reports.html import Page, Section, esc, render, table_html
from pnp_twin.reports.load import ReportError
from pnp_twin.reports.style import PALETTE, rgba, style
from pnp_twin.reports.text import param_label
from pnp_twin.twin.output import write_text
from pnp_twin.twin.scenario import Scenario

log = logging.getLogger(__name__)

SUMMARY_FILE = "calibration.json"
REPORT_FILE = "report.html"


def load_calibration(folder: Path | str) -> dict[str, Any]:
    """The summary a calibration folder holds, or a one-line ReportError."""
    path = Path(folder) / SUMMARY_FILE
    try:
        return dict(json.loads(path.read_text(encoding="utf-8")))
    except FileNotFoundError:
        raise ReportError(f"{folder}: no {SUMMARY_FILE}; run `pnp-twin calibrate` first") from None
    except json.JSONDecodeError as e:
        raise ReportError(f"{path}: not valid JSON ({e.msg}, line {e.lineno})") from None


KPI_LABELS = {  # KPI -> (label, unit) as calibration.json holds it
    "gripping_rate": ("Gripping rate", "%"),
    "throughput": ("Throughput", "parts/s"),
    "part_flow": ("Part flow", "parts/s"),
    "efficiency": ("Efficiency", "fraction"),
    "utilisation": ("Utilisation", "fraction"),
    "cycle_time_mean": ("Mean cycle time", "s"),
    "cycle_time_p95": ("95th percentile cycle time", "s"),
}


def kpi_label(kpi: str) -> str:
    """'gripping_rate' -> 'Gripping rate (%)': an axis title with its unit."""
    label, unit = KPI_LABELS.get(kpi, (kpi.replace("_", " ").capitalize(), ""))
    if not unit and kpi.startswith("cycle_time"):
        unit = "s"
    return f"{label} ({unit})" if unit else label


def field_unit(path: str) -> str:
    """The unit of a dotted scenario path (list elements included) in the Scenario model."""
    model: type[BaseModel] | None = Scenario
    info = None
    for key in path.split("."):
        if key.isascii() and key.isdigit():
            continue
        if model is None or key not in model.model_fields:
            return ""
        info = model.model_fields[key]
        ann = info.annotation
        model = ann if isinstance(ann, type) and issubclass(ann, BaseModel) else None
    extra = info.json_schema_extra if info is not None else None
    unit = extra.get("unit") if isinstance(extra, dict) else None
    return "" if unit in (None, "1") else str(unit).replace("^2", "²")


def field_label(name: str, sep: str = " = ") -> str:
    """A fitted or varied field as an axis title with its unit: 'robots.bin_offset.1' ->
    'Bin offset [1] (m)'; fields fitted as one ('a,b') joined by ``sep``."""
    paths = [p.strip() for p in name.split(",") if p.strip()]
    words = []
    for path in paths:
        keys = path.split(".")
        index = [k for k in keys if k.isdigit()]
        base = ".".join(k for k in keys if not k.isdigit())
        text = param_label(base, unit=False) + (f" [{', '.join(index)}]" if index else "")
        words.append(text)
    unit = field_unit(paths[0]) if paths else ""
    return sep.join(words) + (f" ({unit})" if unit else "")


def _label(info: dict[str, Any], row: dict[str, Any]) -> str:
    def cell(path: str) -> str:
        unit = field_unit(path)
        name = field_label(path).removesuffix(f" ({unit})" if unit else "").lower()
        return f"{name} {row[path]}" + (f" {unit}" if unit else "")

    cells = ", ".join(cell(v) for v in info["varied"])
    return f"{row['point']}: {cells}" if cells else str(row["point"])


def _span(row: dict[str, Any]) -> tuple[float, float]:
    if row["ci_low"] is None:
        return 0.0, 0.0
    low, high = _bounded(row, row["ci_low"], row["ci_high"])
    return high - row["predicted"], row["predicted"] - low


def _bounded(row: dict[str, Any], low: float, high: float) -> tuple[float, float]:
    """A gripping rate's interval cut to [0, 100] %: no line picks more than it is given."""
    if row.get("kpi", "gripping_rate") == "gripping_rate":
        return max(low, 0.0), min(high, 100.0)
    return low, high


def points_figure(info: dict[str, Any], kpi: str) -> go.Figure:
    """Measured and predicted (95 % CI) at every point, for one KPI."""
    rows = [r for r in info["points"] if r["kpi"] == kpi]
    labels = [_label(info, r) for r in rows]
    up, down = zip(*[_span(r) for r in rows], strict=True) if rows else ((), ())
    fig = go.Figure()
    fig.add_scatter(
        x=labels,
        y=[r["target"] for r in rows],
        mode="markers",
        name="measured",
        marker={"symbol": "diamond", "size": 12, "color": PALETTE[1]},
    )
    fig.add_scatter(
        x=labels,
        y=[r["predicted"] for r in rows],
        mode="markers",
        name="twin (95 % CI)",
        marker={"size": 10, "color": PALETTE[0]},
        error_y={"type": "data", "array": list(up), "arrayminus": list(down), "visible": True},
        customdata=[[r["residual"], r["policy"]] for r in rows],
        hovertemplate="%{x}<br>twin %{y:.2f}<br>residual %{customdata[0]:+.2f}"
        "<br>policy %{customdata[1]}<extra></extra>",
    )
    fig.update_xaxes(title="Measured point", type="category")
    fig.update_yaxes(title=kpi_label(kpi))
    return style(
        fig,
        f"Measured vs twin: {kpi_label(kpi)}",
        "each point at the fitted parameters; bars: 95 % CI over the replications",
        height=400,
    )


def curve_figure(info: dict[str, Any], field: str, kpi: str) -> go.Figure:
    """The fitted twin's response across one varied field, with the measured points."""
    rows = [r for r in info["curves"] if r["field"] == field and r["kpi"] == kpi]
    xs = [r["value"] for r in rows]
    fig = go.Figure()
    lows = [
        _bounded(r, r["ci_low"], r["ci_high"])[0] if r["ci_low"] is not None else r["predicted"]
        for r in rows
    ]
    highs = [
        _bounded(r, r["ci_low"], r["ci_high"])[1] if r["ci_high"] is not None else r["predicted"]
        for r in rows
    ]
    fig.add_scatter(
        x=xs + xs[::-1],
        y=highs + lows[::-1],
        fill="toself",
        mode="none",
        fillcolor=rgba(PALETTE[0], 0.15),
        name="95 % CI",
        hoverinfo="skip",
    )
    fig.add_scatter(
        x=xs,
        y=[r["predicted"] for r in rows],
        mode="lines+markers",
        name="fitted twin",
        line={"color": PALETTE[0]},
    )
    meas = [r for r in info["points"] if r["kpi"] == kpi]
    fig.add_scatter(
        x=[r[field] for r in meas],
        y=[r["target"] for r in meas],
        mode="markers",
        name="measured",
        marker={"symbol": "diamond", "size": 12, "color": PALETTE[1]},
    )
    fig.update_xaxes(title=field_label(field))
    fig.update_yaxes(title=kpi_label(kpi))
    others = [field_label(v) for v in info["varied"] if v != field]
    note = f"; {', '.join(others)} as at point 1" if others else ""
    return style(
        fig,
        f"Fitted response: {kpi_label(kpi)} against {field_label(field).lower()}",
        f"best policy at each value{note}",
        height=420,
    )


def profile_figure(info: dict[str, Any]) -> go.Figure:
    """The objective along each parameter near the optimum, the others held at theirs."""
    params = info["params"]
    fig = make_subplots(
        rows=1,
        cols=len(params),
        subplot_titles=[field_label(p["name"], "<br>= ") for p in params],
        horizontal_spacing=0.08,
    )
    margin = float(info.get("near_optimal_margin") or 1.0)
    for j, p in enumerate(params, start=1):
        rows = sorted(
            (r for r in info["profiles"] if r["param"] == p["name"] and not r["param_2"]),
            key=lambda r: r["value"],
        )
        fig.add_scatter(
            x=[r["value"] for r in rows],
            y=[r["objective"] for r in rows],
            mode="lines+markers",
            line={"color": PALETTE[j % len(PALETTE)]},
            showlegend=False,
            row=1,
            col=j,
        )
        fig.add_vline(x=p["value"], line_dash="dot", line_color="#5f6b7a", row=1, col=j)
        fig.add_hline(
            y=info["objective"] + margin, line_dash="dash", line_color="#c0392b", row=1, col=j
        )
        unit = field_unit(p["name"].split(",")[0])
        fig.update_xaxes(title=f"value ({unit})" if unit else "value", row=1, col=j)
    fig.update_yaxes(title="Objective (weighted squared residuals)", col=1)
    return style(
        fig,
        "How well each parameter is determined",
        "objective along each parameter, others at the fit; dotted: fitted value; "
        f"dashed: best + {margin:.3g} (95 %, residual and seed noise)",
        height=440,
        top=140,  # a two-line caption above subplot titles of up to two lines
    )


def pair_figure(info: dict[str, Any], a: str, b: str) -> go.Figure:
    """The objective over a grid of two parameters: a diagonal valley is a trade-off."""
    rows = [r for r in info["profiles"] if r["param"] == a and r["param_2"] == b]
    xs = sorted({r["value"] for r in rows})
    ys = sorted({r["value_2"] for r in rows})
    z = [[math.nan] * len(xs) for _ in ys]
    for r in rows:
        z[ys.index(r["value_2"])][xs.index(r["value"])] = r["objective"]
    fig = go.Figure(
        go.Contour(
            x=xs,
            y=ys,
            z=z,
            colorscale="Viridis_r",
            colorbar={"title": "Objective"},
            contours={"showlabels": True},
        )
    )
    pa = next(p for p in info["params"] if p["name"] == a)
    pb = next(p for p in info["params"] if p["name"] == b)
    fig.add_scatter(
        x=[pa["value"]],
        y=[pb["value"]],
        mode="markers",
        name="fit",
        marker={"symbol": "x", "size": 12, "color": "#c0392b"},
    )
    fig.update_xaxes(title=field_label(a))
    fig.update_yaxes(title=field_label(b))
    return style(
        fig,
        f"Trade-off: {field_label(a, ' = ')} and {field_label(b, ' = ')}",
        "objective over both, the other "
        "parameters at the fit; a long diagonal valley: the data cannot fit both",
        height=440,
    )


def _answer(info: dict[str, Any]) -> str:
    g = [abs(r["residual"]) for r in info["points"] if r["kpi"] == "gripping_rate"]
    worst = max((abs(r["residual"]) for r in info["points"]), default=math.nan)
    fitted = "; ".join(f"{p['name']} = {p['value']:.4g}" for p in info["params"])
    if g:
        first = (
            f"The fitted twin is within {max(g):.2f} points of every measured gripping "
            f"rate ({len(g)} points)."
        )
    else:
        first = f"The fitted twin's largest residual is {worst:.3g} (in the KPI's units)."
    return (
        f'<div class="answer"><p>{esc(first)}</p><p>Fitted: {esc(fitted)}. '
        f"Objective {info['objective']:.4g} after {info['evaluations']} evaluations.</p></div>"
    )


def _determined(info: dict[str, Any]) -> str:
    items = []
    margin = float(info.get("near_optimal_margin") or 1.0)
    for p in info["params"]:
        lo, hi = p["near_optimal"]
        if lo is None or (isinstance(lo, float) and math.isnan(lo)):
            continue
        width = (hi - lo) / (p["high"] - p["low"])
        verdict = "well determined" if width < 0.2 else "poorly determined by these points"
        items.append(
            f"<li><b>{esc(p['name'])}</b>: objective within +{margin:.3g} of the best for "
            f"{lo:.4g} to {hi:.4g} ({100 * width:.0f} % of its bounds): {verdict}.</li>"
        )
    if not items:
        return ""
    why = (
        f"<p class='note'>A value is kept when the objective rises by at most {margin:.3g} "
        "above its best: 3.84 (chi-square, 1 degree of freedom, 95 %) times the variance of "
        "one residual, the larger of what the fit leaves and what the seeds give "
        "(run-to-run noise of the prediction and of the measurement).</p>"
    )
    return f'<ul class="findings">{"".join(items)}</ul>' + why


def _points_table(info: dict[str, Any]) -> str:
    head = ["Point", *(field_label(v) for v in info["varied"]), "KPI", "Measured", "Twin"]
    head += ["95 % CI", "Residual", "Policy"]
    rows = []
    for r in info["points"]:
        ci = ""
        if r["ci_low"] is not None:
            lo, hi = _bounded(r, r["ci_low"], r["ci_high"])
            ci = f'<span style="white-space:nowrap">{lo:.2f} to {hi:.2f}</span>'
        rows.append(
            [
                str(r["point"]),
                *(esc(r[v]) for v in info["varied"]),
                f'<span style="white-space:nowrap">{esc(kpi_label(r["kpi"]))}</span>',
                f"{r['target']:.4g}",
                f"{r['predicted']:.2f}",
                ci,
                f"{r['residual']:+.2f}",
                esc(r["policy"]),
            ]
        )
    return table_html(head, rows)


def _facts(info: dict[str, Any]) -> str:
    facts = [
        ("command", f"<code>{esc(info['command'])}</code>"),
        ("date", esc(info["date"])),
        ("scenario", esc(info["scenario"])),
        ("calibrated scenario file", f"<code>{esc(info['scenario_file'])}</code>"),
        ("measured points", f"<code>{esc(info['targets_file'])}</code>"),
        (
            "prediction",
            esc(
                f"best of {', '.join(info['policies'])}, mean of "
                f"{info['replications']} common-random-number replications of "
                f"{info['duration']:g} s (warm-up {info['warmup']:g} s)"
            ),
        ),
        ("optimiser", esc(info["optimiser"])),
        (
            "evaluations",
            esc(
                f"{info['evaluations']} by the optimiser; "
                f"{info['simulated_points']} points simulated, "
                f"{info['replayed_points']} replayed from the journal"
            ),
        ),
        ("wall time", esc(f"{info['wall_time']:.0f} s")),
    ]
    rows = "".join(f"<tr><th>{k}</th><td>{v}</td></tr>" for k, v in facts)
    return f'<table class="facts">{rows}</table>'


def _pairs(info: dict[str, Any]) -> list[tuple[str, str]]:
    seen = {(r["param"], r["param_2"]) for r in info["profiles"] if r["param_2"]}
    names = [p["name"] for p in info["params"]]
    return sorted(seen, key=lambda ab: (names.index(ab[0]), names.index(ab[1])))


def build_calibration_page(info: dict[str, Any]) -> Page:
    """The report's page (see the module docstring)."""
    kpis: Sequence[str] = info["kpis"]
    g = [abs(r["residual"]) for r in info["points"] if r["kpi"] == "gripping_rate"]
    cards = [
        ("largest |residual|", f"{max(g):.2f} pp" if g else "-", "gripping rate, over the points"),
        ("objective", f"{info['objective']:.3g}", "weighted sum of squared residuals"),
        (
            "parameters",
            str(len(info["params"])),
            f"fitted to {len({r['point'] for r in info['points']})} points",
        ),
        (
            "wall time",
            f"{info['wall_time']:.0f} s",
            f"this run: {info['simulated_points']} points simulated, "
            f"{info['replayed_points']} replayed",
        ),
    ]
    sections = [
        Section(
            "answer",
            "How close the twin comes",
            "At the fitted values, measured against predicted at every point.",
            [_answer(info), *(points_figure(info, k) for k in kpis), _points_table(info)],
        ),
    ]
    curves = [
        curve_figure(info, f, k)
        for f in info["varied"]
        for k in kpis
        if any(r["field"] == f and r["kpi"] == k for r in info["curves"])
    ]
    if curves:
        sections.append(
            Section(
                "response",
                "Fitted response",
                "The calibrated twin across the range of each field the points vary.",
                list(curves),
            )
        )
    determined: list[go.Figure | str] = [_determined(info)]
    if any(not r["param_2"] for r in info["profiles"]):
        determined.append(profile_figure(info))
    determined += [pair_figure(info, a, b) for a, b in _pairs(info)]
    sections.append(
        Section(
            "determined",
            "How well each parameter is determined",
            "A sharp minimum means the points pin the parameter down; a flat "
            "profile or a valley across two parameters means they do not.",
            determined,
        )
    )
    sections.append(Section("run", "What was run", "", [_facts(info)]))
    return Page(
        title=f"Calibration of {info['scenario']}",
        eyebrow="pnp-twin calibrate",
        lead=esc(f"{len(info['params'])} parameter(s) fitted to {info['targets_file']}."),
        cards=cards,
        sections=sections,
        footer=esc(f"pnp-twin · {info['date']}"),
    )


def build_calibration_report(folder: Path | str, out: Path | str | None = None) -> Path:
    """Write the report of a calibration folder to ``out`` (default ``DIR/report.html``)."""
    target = Path(out) if out is not None else Path(folder) / REPORT_FILE
    page = render(build_calibration_page(load_calibration(folder)))
    write_text(page, target)
    log.info("calibration report written to %s", target)
    return target
