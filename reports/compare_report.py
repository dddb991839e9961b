"""The report of two policies on one seed (``pnp-twin compare``), from their record tables.

The same seed feeds both the same parts (common random numbers), so part k is the same part
under either policy: the page says which parts one policy grips and the other loses, and
replays both runs in step, those parts highlighted, the running difference in G beside the
clock.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pandas as pd

from pnp_twin.reports.html import Page, Section, esc, render, table_html
from pnp_twin.reports.record_figures import Animation
from pnp_twin.reports.replay_data import replay_data
from pnp_twin.reports.replay_page import replay_html, replay_intro
from pnp_twin.reports.text import fmt_pct
from pnp_twin.twin.output import write_text


@dataclass(frozen=True)
class RunRecords:
    """One policy's run: its KPIs and record tables."""

    kpis: Mapping[str, Any]
    parts: pd.DataFrame
    spans: pd.DataFrame


def swapped_parts(a: pd.DataFrame, b: pd.DataFrame, warmup: float) -> tuple[int, int]:
    """(parts a grips and b loses, parts b grips and a loses), fed after the warm-up."""
    cols = ["part", "fed_at", "outcome"]
    both = a[cols].merge(b[["part", "outcome"]], on="part", suffixes=("_a", "_b"))
    both = both[both["fed_at"] >= warmup]
    a_only = (both["outcome_a"] == "picked") & (both["outcome_b"] != "picked")
    b_only = (both["outcome_b"] == "picked") & (both["outcome_a"] != "picked")
    return int(a_only.sum()), int(b_only.sum())


def compare_headline(runs: Sequence[RunRecords], warmup: float) -> str:
    """'lookahead grips 78.1 % of the parts, SD 69.0 %: +9.1 points on seed 1; ...'."""
    (a, b) = runs
    ga, gb = float(a.kpis["gripping_rate"]), float(b.kpis["gripping_rate"])
    better, worse = (b, a) if gb > ga else (a, b)
    gain = abs(gb - ga)
    a_only, b_only = swapped_parts(a.parts, b.parts, warmup)
    text = (
        f"{better.kpis['policy']} grips {fmt_pct(better.kpis['gripping_rate'])} of the parts, "
        f"{worse.kpis['policy']} {fmt_pct(worse.kpis['gripping_rate'])}: "
        f"{gain:.1f} points apart on seed {a.kpis.get('seed')}"
    )
    text += (
        f". {a_only} parts {a.kpis['policy']} grips are lost by {b.kpis['policy']}, "
        f"{b_only} the other way round (one seed: use a study for a confidence interval)."
    )
    return text


def kpi_table(runs: Sequence[RunRecords]) -> str:
    """The two runs' KPIs side by side."""
    rows = []
    for label, key, fmt in (
        ("Gripping rate G", "gripping_rate", lambda v: fmt_pct(v, 2)),
        ("Parts presented", "parts_presented", str),
        ("Parts picked", "parts_picked", str),
        ("Parts lost", "parts_missed", str),
        ("Throughput (parts/s)", "throughput", lambda v: f"{v:.3f}"),
        ("Utilisation (mean)", "utilisation", lambda v: fmt_pct(100 * v)),
    ):
        rows.append([esc(label), *(esc(fmt(r.kpis[key])) for r in runs)])
    header = ["KPI", *(esc(r.kpis.get("policy")) for r in runs)]
    return table_html(header, rows, left=1)


def build_compare_page(
    runs: Sequence[RunRecords],
    scenario: Mapping[str, Any],
    animation: Animation | None = None,
    command: str = "",
) -> Page:
    """The page of two runs of one scenario and seed under two policies."""
    if len(runs) != 2:
        raise ValueError("compare draws two runs")
    animation = animation or Animation()
    warmup = float(scenario.get("warmup") or 0.0)
    datas = [
        replay_data(
            r.parts,
            r.spans,
            scenario,
            r.kpis.get("seed"),
            animation.start,
            animation.seconds,
            f"{r.kpis.get('policy')}",
        )
        for r in runs
    ]
    intro = replay_intro(datas[0]) + esc(
        " Both runs in step; a yellow halo marks a part one policy grips and the other loses."
    )
    headline = compare_headline(runs, warmup)
    lead = esc(str(scenario.get("description") or ""))
    if command:
        lead += f" · <code>{esc(command)}</code>"
    return Page(
        title=f"{scenario.get('name')}: {runs[0].kpis.get('policy')} vs "
        f"{runs[1].kpis.get('policy')}",
        eyebrow="pnp-twin report<span class='badge'>compare</span>",
        lead=lead,
        cards=[
            (str(r.kpis.get("policy")), fmt_pct(r.kpis["gripping_rate"]), "gripping rate")
            for r in runs
        ]
        + [("Seed", str(runs[0].kpis.get("seed")), "the same parts for both")],
        sections=[
            Section(
                "answer", "The answer", "", [f'<div class="answer"><p>{esc(headline)}</p></div>']
            ),
            Section("replay", "Watch both", intro, [replay_html(datas, "compare")]),
            Section(
                "kpis", "KPIs", esc(f"Parts fed after the {warmup:g} s warm-up."), [kpi_table(runs)]
            ),
        ],  # fmt: skip
        footer=esc("Generated by pnp-twin compare · self-contained: opens offline."),
    )


def build_compare_report(
    runs: Sequence[RunRecords],
    scenario: Mapping[str, Any],
    out: Path | str,
    animation: Animation | None = None,
    command: str = "",
) -> Path:
    """Write the comparison report to ``out`` atomically; returns the path."""
    return write_text(render(build_compare_page(runs, scenario, animation, command)), out)


__all__ = ["RunRecords", "build_compare_page", "build_compare_report", "swapped_parts"]
