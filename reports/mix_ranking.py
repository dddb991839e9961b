"""The rule-mix search's section: every evaluated mix in a ranked table, one column per
robot's rule, its gripping rate with the CI and the paired difference to the best mix."""

from __future__ import annotations

import math
from typing import Any

from pnp_twin.reports import figures
from pnp_twin.reports.html import Section, esc, table_html
from pnp_twin.reports.load import Study
from pnp_twin.reports.text import fmt_pct, fmt_pm


def mix_table(study: Study) -> str:
    """Every evaluated mix, ranked: one column per robot's rule, G with its CI, and the
    paired difference to the best mix."""
    assert study.mix is not None
    ranked = study.mix.get("ranked") or []
    n = max((len(str(r["mix"]).split(",")) for r in ranked), default=0)
    paired = study.paired
    diff: dict[str, tuple[float, float, float]] = {}
    if paired is not None and not paired.empty:
        for _, p in paired.iterrows():
            diff[str(p["policy"])] = (p["diff_mean"], p["diff_ci_low"], p["diff_ci_high"])
    priced = any(r.get("total_cost") is not None for r in ranked)
    rows = []
    for i, r in enumerate(ranked, start=1):
        d = diff.get(str(r["mix"]))
        vs = "best" if i == 1 else "–"
        if d is not None and i > 1:
            vs = f"{d[0]:+.2f}" + (
                f' <span class="pm">[{d[1]:+.2f}, {d[2]:+.2f}]</span>'
                if math.isfinite(d[1])
                else ""
            )
        rows.append(
            [str(i)]
            + [esc(rule) for rule in str(r["mix"]).split(",")]
            + [
                esc(fmt_pct(float(r["gripping_rate_mean"]), 2))
                + f'<span class="pm">{esc(fmt_pm(r.get("ci_low"), r.get("ci_high"), 2))}</span>',
                vs,
            ]
            + ([_cost(r.get("total_cost"))] if priced else [])
        )
    header = ["Rank", *(f"Robot {k}" for k in range(1, n + 1))]
    header += ["Gripping rate (%)", "Difference to the best, points (paired 95 % CI)"]
    header += ["Total cost"] if priced else []
    classes = ["best" if i == 0 else "" for i in range(len(rows))]
    return table_html(header, rows, left=n + 1, classes=classes, scroll=len(rows) > 14)


def _cost(value: Any) -> str:
    return "–" if value is None or not math.isfinite(float(value)) else f"{float(value):,.0f}"


def mix_section(study: Study) -> Section | None:
    if study.mix is None:
        return None
    ranked = study.mix.get("ranked") or []
    items: list[Any] = []
    if ranked:
        items.append(mix_table(study))
        items.append(figures.mix_figure(study.mix))
    m = study.mix
    why = {
        "budget": "it stopped at its budget",
        "converged": "it stopped when constructions found no new mix",
    }.get(str(m.get("stopped")), "every mix")
    intro = (
        f"{m.get('evaluated', len(ranked))} mixes evaluated ({m.get('method', 'search')}: {why}"
        "), ranked by mean gripping rate over the same replications (common random "
        "numbers). Per-robot dispatching rules, searched as Huang et al. did: the static "
        "baseline a learned policy has to beat."
    )
    return Section("mix", "Rule-mix ranking", esc(intro), items)
