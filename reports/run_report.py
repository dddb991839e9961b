"""The report of one run (``pnp-twin run --report FILE.html``), from its record tables.

The command simulates; this module only draws what the run recorded: the answer in one
sentence, the KPI table, the robots (time shares, parts passed on and lost), the activity
timeline, the belt animation and Welch's warm-up plot of this one replication.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import pandas as pd

from pnp_twin.reports import record_figures, welch
from pnp_twin.reports.html import Page, Section, esc, render, table_html
from pnp_twin.reports.replay_data import replay_data
from pnp_twin.reports.replay_page import replay_html, replay_intro
from pnp_twin.reports.text import fmt_pct, fmt_seconds
from pnp_twin.twin.output import write_text

TIMELINE_SECONDS = 20.0


def run_headline(kpis: Mapping[str, Any]) -> str:
    """'SD grips 72.3 % of the parts on this line; ...' in one sentence."""
    robots = kpis.get("robots") or []
    busiest = max(robots, key=lambda r: r["utilisation"], default=None)
    out = (
        f"With {kpis.get('policy')} the line grips {fmt_pct(kpis['gripping_rate'])} of the "
        f"{kpis['parts_presented']} parts presented ({kpis['throughput']:.2f} of "
        f"{kpis['part_flow']:.2f} parts/s), losing {kpis['parts_missed']} to the return "
        "conveyor"
    )
    if busiest is not None:
        out += f"; robot {busiest['robot']} is the busiest at "
        out += f"{fmt_pct(100 * busiest['utilisation'])} utilisation"
    return out + " (one run: no confidence interval; use a study for one)."


def value_text(kpis: Mapping[str, Any]) -> str:
    """On a line with kinds: the value rate beside G, and which kinds no robot picks, as a
    paragraph of the answer box; '' on a line of one kind."""
    if not kinds_of(kpis):
        return ""
    text = f"Value rate {fmt_pct(kpis['value_rate'])}: the share of the presented value "
    text += "(every kind's) that was gripped"
    n = int(kpis.get("parts_passed_by_design") or 0)
    if n:
        text += f"; {n} parts of kinds no robot picks passed on by design, left out of G"
    text += "."
    return f"<p>{esc(text)}</p>"


def kpi_rows(kpis: Mapping[str, Any]) -> str:
    """The line's KPIs as a two-column table, shares in %."""
    rows = [
        ("Gripping rate G", fmt_pct(kpis["gripping_rate"], 2)),
        *(
            [("Value rate", fmt_pct(kpis["value_rate"], 2) + " of the presented value gripped")]
            if kinds_of(kpis)
            else []
        ),
        (
            "Parts presented / picked / lost",
            "{} / {} / {}".format(
                kpis["parts_presented"], kpis["parts_picked"], kpis["parts_missed"]
            ),
        ),
        ("Throughput / part flow", f"{kpis['throughput']:.3f} / {kpis['part_flow']:.3f} parts/s"),
        (
            "Efficiency",
            fmt_pct(100 * kpis["efficiency"])
            + " of min(part flow, robots' measured cycle rate: picks per busy second)",
        ),
        ("Utilisation (mean of the robots)", fmt_pct(100 * kpis["utilisation"])),
        (
            "Cycle time mean / p95",
            f"{kpis['cycle_time_mean']:.3f} / {kpis['cycle_time_p95']:.3f} s",
        ),
    ]
    rows += outfeed_rows(kpis)
    body = "".join(f"<tr><th>{esc(k)}</th><td>{esc(v)}</td></tr>" for k, v in rows)
    return f'<table class="facts"><tbody>{body}</tbody></table>'


def outfeed_rows(kpis: Mapping[str, Any]) -> list[tuple[str, str]]:
    """On a line placing onto an outfeed: its fill rate, slots filled and parts held."""
    if "fill_rate" not in kpis:
        return []
    return [
        (
            "Fill rate (containers that left full)",
            f"{fmt_pct(kpis['fill_rate'], 1)}: {kpis['containers_full']} of "
            f"{kpis['containers']} containers ({kpis['containers_unfilled']} left unfilled)",
        ),
        ("Slots filled", f"{kpis['slots_filled_per_s']:.3f} per s"),
        (
            "Parts held for want of a free slot",
            f"{kpis['parts_held']} ({kpis['hold_time']:.1f} s in all; robots held "
            f"{fmt_pct(100 * kpis['hold'])} of their time; {kpis['parts_held_at_end']} still "
            "held at the end)",
        ),
    ]


def robot_rows(kpis: Mapping[str, Any]) -> str:
    """One row per robot, shares in %."""
    header = ["Robot", "Workspace (m)", "Picks", "Utilisation (%)", "NooP (%)", "Down (%)"]
    header += ["Availability (%)", "Passed on (parts)", "Lost (parts)"]
    rows = []
    for r in kpis.get("robots") or []:
        a, b = r["workspace"]
        rows.append(
            [
                str(r["robot"]),
                f"{a:g}–{b:g}",
                str(r["picks"]),
                f"{100 * r['utilisation']:.1f}",
                f"{100 * r['noop']:.1f}",
                f"{100 * r['down']:.1f}",
                f"{100 * r['availability']:.1f}",
                str(r["passed_on"]),
                str(r["lost"]),
            ]
        )
    return table_html(header, rows, left=0)


def kinds_of(kpis: Mapping[str, Any]) -> dict[str, dict[str, Any]]:
    """The per-kind KPIs of a line with kinds of part (``kpis["kinds"]``); {} otherwise."""
    return dict(kpis.get("kinds") or {})


def _pct_or_dash(value: Any) -> str:
    return fmt_pct(float(value), 1) if value is not None and math.isfinite(value) else "–"


def by_design_text(kpis: Mapping[str, Any]) -> str:
    """Which kinds no robot picks: 'No robot picks residual (253 parts): they pass on to the
    end of the belt by design and are left out of G.'; every kind picked said so."""
    kinds = kinds_of(kpis)
    untargeted = [(k, v) for k, v in kinds.items() if not v.get("targeted", True)]
    if not untargeted:
        return "Every kind is picked by some robot: no part passes on by design."
    names = [f"{k} ({v['parts_passed_by_design']} parts)" for k, v in untargeted]
    listed = names[0] if len(names) == 1 else ", ".join(names[:-1]) + " or " + names[-1]
    return (
        f"No robot picks {listed}: {'it passes' if len(names) == 1 else 'they pass'} on to the "
        "end of the belt by design, counted apart and left out of the gripping rate G."
    )


def kind_rows(kpis: Mapping[str, Any]) -> str:
    """One row per kind of part: value, presented, picked, lost, passed on by design, G of
    the kind and the % of its value gripped ('–' where not defined)."""
    header = ["Kind", "Value (per part)", "Presented", "Picked", "Lost"]
    header += ["Passed on by design", "G (%)", "Value gripped (%)"]
    rows = []
    for name, k in kinds_of(kpis).items():
        worth = float(k.get("value_presented") or 0.0)
        share = 100.0 * float(k.get("value_picked") or 0.0) / worth if worth > 0 else math.nan
        rows.append(
            [
                esc(name) + ("" if k.get("targeted", True) else " (not targeted)"),
                esc(f"{float(k['value']):g}"),
                esc(k["parts_presented"]),
                esc(k["parts_picked"]),
                esc(k["parts_lost"]),
                esc(k["parts_passed_by_design"]),
                esc(_pct_or_dash(k.get("gripping_rate"))),
                esc(_pct_or_dash(share)),
            ]
        )
    return table_html(header, rows, left=1)


SETTINGS = (  # (field, header, unit) of the per-robot settings table
    ("arm_speed", "Arm speed", "m/s"),
    ("pick_time", "Pick time", "s"),
    ("place_time", "Place time", "s"),
    ("acceleration", "Acceleration", "m/s²"),
    ("bin_offset", "Bin offset", "m"),
    ("mtbf", "MTBF", "s"),
    ("mttr", "MTTR", "s"),
)


SHAPE_SETTINGS = (  # (field, header, unit): a column only where some robot overrides it
    ("side", "Side", ""),
    ("reach", "Reach", "m"),
    ("base_offset", "Base offset", "m"),
    ("kinds", "Kinds", ""),
)


def settings_rows(scenario: Mapping[str, Any]) -> str:
    """Each robot's settings, one row per robot: the shared value, or its override (marked
    ●); empty when the scenario overrides nothing."""
    robots = scenario.get("robots") or {}
    overrides = {int(o["robot"]): o for o in robots.get("overrides") or [] if "robot" in o}
    if not overrides:
        return ""
    n = int(robots.get("count") or max(overrides))
    alternate = robots.get("side") == "alternate"  # odd robots upper, even robots lower
    shown = SETTINGS + tuple(
        (key, h, u)
        for key, h, u in SHAPE_SETTINGS
        if any(o.get(key) is not None for o in overrides.values()) or (key == "side" and alternate)
    )
    header = ["Robot", *(f"{h} ({u})" if u else h for _, h, u in shown)]
    rows = []
    for i in range(1, n + 1):
        own = overrides.get(i) or {}
        row = [str(i)]
        for key, _, _ in shown:
            value = own.get(key)
            if value is not None:
                row.append(f"<b>{esc(_num(value) or 'all')}</b> ●")
            else:
                shared = robots.get(key)
                if key == "side" and alternate:
                    shared = "upper" if i % 2 else "lower"
                row.append(esc(_num(shared) or "all") if shared is not None else "–")
        rows.append(row)
    note = '<p class="note">● overridden for this robot (robots.overrides); the rest are '
    note += "the line's shared values. An MTBF of 0 means no breakdowns.</p>"
    return table_html(header, rows, left=0) + note


def _num(value: Any) -> str:
    if isinstance(value, list | tuple):
        return ", ".join(_num(v) for v in value)
    return f"{float(value):g}" if isinstance(value, int | float) else str(value)


def build_run_page(
    kpis: Mapping[str, Any],
    parts: pd.DataFrame,
    spans: pd.DataFrame,
    scenario: Mapping[str, Any],
    command: str = "",
    animation: record_figures.Animation | None = None,
) -> Page:
    """The one-run report as a Page."""
    duration = float(scenario.get("duration") or kpis["window"][1])
    warmup = float(scenario.get("warmup") or 0.0)
    n = int((scenario.get("robots") or {}).get("count") or len(kpis.get("robots") or []))
    t0 = warmup if duration - warmup >= TIMELINE_SECONDS else 0.0
    t1 = min(t0 + TIMELINE_SECONDS, duration)
    row = {k: v for k, v in kpis.items() if not isinstance(v, dict | list)}
    for r in kpis.get("robots") or []:
        row.update(
            {f"r{r['robot']}_{k}": v for k, v in r.items() if k not in ("robot", "workspace")}
        )
    results = pd.DataFrame([row | {"policy": kpis.get("policy")}])
    items: list[Any] = [record_figures.robots_figure(results, {}, str(kpis.get("policy")))]
    records: list[Any] = []
    if t1 > t0:
        records.append(record_figures.timeline_figure(parts, spans, t0, t1, n))
    if len(parts):
        animation = animation or record_figures.Animation()
        records.append(
            record_figures.animated_belt(parts, dict(scenario), animation, warmup, duration)
        )
    sections = [
        Section(
            "answer",
            "The answer",
            "",
            [f'<div class="answer"><p>{esc(run_headline(kpis))}</p>{value_text(kpis)}</div>'],
        ),
        replay_section(kpis, parts, spans, scenario, animation),
        Section(
            "kpis",
            "KPIs",
            esc(f"Parts fed in [{warmup:g}, {duration:g}) s."),
            [kpi_rows(kpis), robot_rows(kpis)],
        ),
        Section(
            "kinds",
            "Kinds of part",
            esc(
                "Each kind's parts fed in the window; G per kind over its parts, value "
                "gripped as % of the value presented."
            ),
            [f'<div class="answer"><p>{esc(by_design_text(kpis))}</p></div>', kind_rows(kpis)]
            if kinds_of(kpis)
            else [],
        ),
        Section(
            "settings",
            "Per-robot settings",
            esc("Where the robots differ: each robot's settings, its overrides marked."),
            [settings_rows(scenario)] if settings_rows(scenario) else [],
        ),
        Section("robots", "Robots", "", items),
        Section("run", "The run up close", "", records),
    ]
    series = pd.DataFrame({welch.COLUMN: [kpis.get(welch.COLUMN) or []]})
    got = welch.welch_items(
        series, duration, warmup, f"{kpis.get('policy')}, seed {kpis.get('seed')}"
    )
    if got is not None:
        fig, text, drifting = got
        box = f'<div class="{"warn" if drifting else "answer"}"><p>{esc(text)}</p></div>'
        sections.append(
            Section(
                "warmup",
                "Warm-up",
                esc(
                    "Welch's plot of this run's gripping rate over time; a study's "
                    "replications give a steadier curve."
                ),
                [box, fig],
            )
        )
    lead = esc(str(scenario.get("description") or ""))
    if command:
        lead += f" · <code>{esc(command)}</code>"
    return Page(
        title=f"{kpis.get('scenario')}: one run",
        eyebrow="pnp-twin report<span class='badge'>run</span>",
        lead=lead,
        cards=[
            ("Gripping rate", fmt_pct(kpis["gripping_rate"]), f"policy {kpis.get('policy')}"),
            *(
                [("Value rate", fmt_pct(kpis["value_rate"]), "of the value presented")]
                if kinds_of(kpis)
                else []
            ),
            *(
                [("Fill rate", fmt_pct(kpis["fill_rate"]), "of the containers left full")]
                if "fill_rate" in kpis
                else []
            ),
            ("Throughput", f"{kpis['throughput']:.2f}", "parts/s"),
            ("Robots", str(n), str(kpis.get("termination") or "")),
            ("Simulated", fmt_seconds(duration), f"of which {warmup:g} s warm-up"),
        ],
        sections=[s for s in sections if s.items],
        footer=esc("Generated by pnp-twin from one run · self-contained: opens offline."),
    )


def replay_section(
    kpis: Mapping[str, Any],
    parts: pd.DataFrame,
    spans: pd.DataFrame,
    scenario: Mapping[str, Any],
    animation: record_figures.Animation | None = None,
) -> Section:
    """The replay of the run over the animation's window (empty without parts)."""
    if not len(parts):
        return Section("replay", "Watch the run", "", [])
    animation = animation or record_figures.Animation()
    data = replay_data(
        parts,
        spans,
        scenario,
        kpis.get("seed"),
        animation.start,
        animation.seconds,
        f"{kpis.get('policy')}, seed {kpis.get('seed')}",
    )
    return Section("replay", "Watch the run", replay_intro(data), [replay_html([data])])


def build_run_report(
    kpis: Mapping[str, Any],
    parts: pd.DataFrame,
    spans: pd.DataFrame,
    scenario: Mapping[str, Any],
    out: Path | str,
    command: str = "",
    animation: record_figures.Animation | None = None,
) -> Path:
    """Write the one-run report to ``out`` atomically; returns the path."""
    page = build_run_page(kpis, parts, spans, scenario, command, animation)
    return write_text(render(page), out)


__all__ = ["build_run_page", "build_run_report", "run_headline"]
