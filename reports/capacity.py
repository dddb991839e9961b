"""The capacity report: one self-contained page from a ``pnp-twin capacity`` folder.

It reads ``DIR/capacity.json`` only (``pnp_twin.studies.capacity`` writes it; nothing is
simulated here): the answer first ("With 6 robots you can promise ... parts/s"), then the
curve of G against part flow with its confidence band, the target and the three crossings
(the flow met with confidence, the mean's, the upper bound's), a what-if panel over the
evaluated flows and the rules (each rule's runs read back from ``DIR/evals/``), and every
evaluated flow.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import plotly.graph_objects as go

from pnp_twin.reports.html import Page, Section, esc, render, table_html
from pnp_twin.reports.load import ReportError, read_json
from pnp_twin.reports.style import PALETTE, cap_percent, rgba, style
from pnp_twin.reports.text import fmt_pct, param_label, param_value
from pnp_twin.reports.whatif import whatif_html
from pnp_twin.twin.output import write_text
from pnp_twin.twin.stats import t_interval

SUMMARY_FILE = "capacity.json"
REPORT_FILE = "report.html"


def load_capacity(folder: Path | str) -> dict[str, Any]:
    """capacity.json of ``folder``, or a one-line ReportError."""
    path = Path(folder) / SUMMARY_FILE
    if not path.is_file():
        raise ReportError(f"{folder}: no {SUMMARY_FILE}; run `pnp-twin capacity` first")
    return read_json(path)


def auto_text(c: dict[str, Any]) -> str:
    """' The replications were chosen by -r auto: 5 → 10 → 20 until ...' (empty without)."""
    a = c.get("auto")
    if not a:
        return ""
    reached = a["reached"]
    how = f"{100 * reached:.1f} %" if reached != float("inf") else "no promise"
    return (
        f" The replications were chosen by -r auto ({' → '.join(map(str, a['replications']))}),"
        f" until the promise sat within {100 * a['gap']:g} % of the mean crossing (reached: "
        f"{how})."
    )


def runs_text(c: dict[str, Any]) -> str:
    """'120 runs simulated, 40 replayed from evals/' (older folders counted flows)."""
    if "runs_simulated" in c:
        return f"{c['runs_simulated']} runs simulated, {c['runs_replayed']} replayed from evals/"
    return f"{c.get('simulated')} flows simulated, {c.get('replayed')} replayed from evals/"


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
    crossings = (
        ("ci_low", "promise", "solid", "top left"),
        ("max_rate", "mean crosses", "dot", "top right"),
        ("ci_high", "upper crosses", "dash", "bottom right"),
    )
    search = c.get("search") or {}
    for key, label, dash, side in crossings:  # labels on alternating sides and heights, so
        x = c.get(key)  # close crossings do not print over each other
        if x is not None and search.get(key, "found") == "found":
            fig.add_vline(
                x=x,
                line={"color": "#2a9d8f", "width": 1.5, "dash": dash},
                annotation_text=f"{label}: {x:.3g}",
                annotation_position=side,
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
    header = ["Part flow (parts/s)", "Rule with the highest lower bound", "Mean G (best)"]
    header += ["CI of the best rule's G", "Promised"]
    return table_html(header, rows, scroll=len(rows) > 14)


def rule_runs(folder: Path | str, c: dict[str, Any]) -> dict[float, dict[str, list[float]]]:
    """G of every replication of every rule at each flow of the curve, read back from the
    study's journal (``evals/``, as ``pnp_twin.studies.capacity`` keeps it: one record per
    flow, labelled 'flow RATE'); {} where the journal is absent or holds other runs."""
    rates = {f"flow {p['rate']:g}": float(p["rate"]) for p in c.get("curve") or []}
    rules, n = list(c.get("rules") or []), int(c.get("replications") or 0)
    out: dict[float, dict[str, list[float]]] = {}
    evals = Path(folder) / "evals"
    for path in sorted(evals.glob("*.json")) if evals.is_dir() else []:
        try:
            record = json.loads(path.read_text(encoding="utf-8"))
            rate = rates.get(str(record.get("label")))
            runs = record["runs"]
            if rate is None or list(record.get("policies") or []) != rules:
                continue
            got = {r: [float(x["gripping_rate"]) for x in runs[r]] for r in rules}
        except (ValueError, KeyError, TypeError, AttributeError, OSError):
            continue  # a damaged or foreign record: the curve's best rule still shows
        if all(len(v) == n for v in got.values()):
            out[rate] = got
    return out


def whatif_section(c: dict[str, Any], folder: Path | str | None = None) -> Section | None:
    """Drop-downs over the evaluated flows and the rules: G with its interval (at the
    selection-safe level the curve uses) from the stored runs; nothing is simulated."""
    curve = c.get("curve") or []
    if not curve:
        return None
    level = float(c.get("confidence_each") or c.get("confidence") or 0.95)
    runs = rule_runs(folder, c) if folder is not None else {}
    target = float(c["target"])
    rows = []
    for p in curve:
        rate = float(p["rate"])
        found = runs.get(rate) or {}
        stats = {r: (b["mean"], b["low"], b["high"]) for r, b in (p.get("rules") or {}).items()}
        stats = stats or {r: t_interval(g, level) for r, g in found.items()}
        if not stats:  # no journal: the best rule of the curve only
            stats = {str(p["policy"]): (p["mean"], p["low"], p["high"])}
        for rule, (mean, low_t, high_t) in stats.items():
            low = max(low_t, 0.0) if math.isfinite(low_t) else None
            high = min(high_t, 100.0) if math.isfinite(high_t) else None
            notes = ["the best rule at this flow"] if rule == p["policy"] and len(stats) > 1 else []
            if low is not None:
                notes.append("meets the target" if low >= target else "misses it")
            rows.append(
                {
                    "values": {"feeder.rate": rate},
                    "policy": rule,
                    "mean": mean,
                    "low": low,
                    "high": high,
                    "note": ", ".join(notes),
                }
            )
    promise = c.get("ci_low") if c.get("ci_low") is not None else c.get("max_rate")
    at = min(curve, key=lambda p: abs(float(p["rate"]) - float(promise or p["rate"])))
    start = {"feeder.rate": float(at["rate"]), "policy": at["policy"]}
    several = len(c.get("rules") or []) > 1
    each = f"{100 * level:.4g} %" + (" per rule (Bonferroni)" if several else "")
    panel = whatif_html(["feeder.rate"], rows, each, start, target=float(c["target"]))
    intro = "Choose a part flow the search evaluated and a rule: the gripping rate measured "
    intro += f"there, with its interval against the target of {fmt_pct(target)} (from the "
    intro += "stored runs; nothing is simulated)."
    return Section("whatif", "What if", esc(intro), [panel])


def config_name(choice: dict[str, Any]) -> str:
    """'Robots 3 · arm speed 4 m/s' for a configuration's choice."""
    words = [param_value(k, v, lower=bool(i)) for i, (k, v) in enumerate(choice.items())]
    return " · ".join(words) or "as given"


def configurations_figure(c: dict[str, Any]) -> go.Figure:
    """One curve of G against part flow per configuration (best rule at each flow), each
    with its CI band, and the target."""
    fig = go.Figure()
    lows: list[float] = []
    highs: list[float] = []
    for i, one in enumerate(c.get("configurations") or []):
        curve = one.get("curve") or []
        xs = [p["rate"] for p in curve]
        lo, hi = [p["low"] for p in curve], [p["high"] for p in curve]
        lows, highs = lows + lo, highs + hi
        color, name = PALETTE[i % len(PALETTE)], config_name(one["choice"])
        fig.add_scatter(
            x=xs + xs[::-1],
            y=hi + lo[::-1],
            fill="toself",
            mode="none",
            fillcolor=rgba(color, 0.12),
            legendgroup=name,
            showlegend=False,
            hoverinfo="skip",
        )
        fig.add_scatter(
            x=xs,
            y=[p["mean"] for p in curve],
            mode="lines+markers",
            name=name,
            legendgroup=name,
            line={"color": color},
            hovertemplate=f"{esc(name)}<br>%{{x:.3g}} parts/s: G = %{{y:.1f}} %<extra></extra>",
        )
    target = float(c["target"])
    fig.add_hline(
        y=target,
        line={"color": "#c0392b", "dash": "dash"},
        annotation_text=f"target {fmt_pct(target)}",
        annotation_position="bottom left",
    )
    fig.update_xaxes(title="Part flow (parts/s)")
    fig.update_yaxes(title="Gripping rate (%)", ticksuffix=" %")
    cap_percent(fig, [*lows, target], [*highs, target])
    level = 100 * float(c.get("confidence") or 0.95)
    return style(
        fig,
        "Gripping rate against part flow, per configuration",
        f"best rule at each flow · bands: {level:g} % CI · same seeds at every flow",
        height=460,
    )


def configurations_table(c: dict[str, Any]) -> str:
    """Each configuration's promise, mean crossing and upper crossing."""
    configs = c.get("configurations") or []
    paths = list(configs[0]["choice"]) if configs else []

    def rate(x: Any) -> str:
        return "–" if x is None else f"{float(x):.3g}"

    rows = [
        [esc(one["choice"].get(p)) for p in paths]
        + [
            esc(one.get("policy") or "–"),
            rate(one.get("ci_low")),
            rate(one.get("max_rate")),
            rate(one.get("ci_high")),
        ]
        for one in configs
    ]
    header = [param_label(p) for p in paths] + ["Rule of the promise", "Promise (parts/s)"]
    header += ["Mean crossing", "Upper crossing"]
    return table_html(header, rows, left=len(paths) + 1, scroll=len(rows) > 14)


def configurations_section(c: dict[str, Any]) -> Section:
    """The curves and the table of every configuration of ``--vary``."""
    intro = (
        f"One root-finding search per configuration, at G ≥ {c['target']:g} %; the answer "
        "above and the what-if panel are the first configuration's."
    )
    return Section(
        "configurations",
        "Every configuration",
        esc(intro),
        [configurations_figure(c), configurations_table(c)],
    )


def build_capacity_page(c: dict[str, Any], folder: Path | str | None = None) -> Page:
    """The capacity report as a Page."""
    conf = 100 * float(c.get("confidence") or 0.95)
    answer = f'<div class="answer"><p>{esc(c["text"])}</p>'
    answer += (
        "<p>"
        + esc(
            f"Flows are found by root finding (doubling or halving from the scenario's flow, "
            f"then bisection to {100 * float(c.get('tolerance') or 0.01):g} %), not a grid; "
            f"{c['evaluated']} flows evaluated with {c['replications']} replications each "
            f"and common random numbers.{auto_text(c)}"
        )
        + "</p></div>"
    )
    lo, hi, mid = c.get("ci_low"), c.get("ci_high"), c.get("max_rate")
    upper_open = (c.get("search") or {}).get("ci_high") == "above"
    cards = [
        (
            "Promise",
            "–" if lo is None else f"{lo:.3g} parts/s",
            f"G ≥ {c['target']:g} % at {conf:g} %"
            + (f" running {c['policy']}" if c.get("policy") and lo is not None else ""),
        ),
        ("Mean crossing", "–" if mid is None else f"{mid:.3g} parts/s", "mean G = target"),
        (
            "Upper crossing",
            "not found" if hi is None or upper_open else f"{hi:.3g} parts/s",
            "still reached at the highest flow tried"
            if hi is None or upper_open
            else f"above it: missed with {conf:g} % confidence",
        ),
        ("Robots", str(c.get("robots")), ", ".join(c.get("rules") or [])),
    ]
    facts = [
        ("Scenario", esc(str(c.get("scenario_name") or ""))),
        ("Rules", esc(", ".join(c.get("rules") or []))),
        (
            "Runs",
            esc(
                f"{c['replications']} replications per flow, {c.get('duration', 0):g} s each "
                f"({c.get('warmup', 0):g} s warm-up); {runs_text(c)}"
            ),
        ),
        ("Command", f"<code>{esc(c.get('command') or '')}</code>"),
    ]
    body = "".join(f"<tr><th>{k}</th><td>{v}</td></tr>" for k, v in facts)
    sections = [
        Section("answer", "The answer", "", [answer, capacity_figure(c)]),
        *[x for x in [whatif_section(c, folder)] if x is not None],
        Section(
            "setup", "What was run", "", [f'<table class="facts"><tbody>{body}</tbody></table>']
        ),
        Section("flows", "Every flow evaluated", "", [flows_table(c)]),
    ]
    if len(c.get("configurations") or []) > 1:
        sections.insert(1, configurations_section(c))
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
    return write_text(render(build_capacity_page(c, folder)), target)
