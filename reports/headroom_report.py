"""The headroom study's page: its answer, then one table (no scripts, opens offline).

A pure function from the study's JSON (:meth:`pnp_twin.studies.headroom.Headroom.to_json`)
to one HTML string.
"""

from __future__ import annotations

import html
import math
from typing import Any

CSS = """
body { font:15px/1.5 "Segoe UI", Roboto, Arial, sans-serif; color:#1d2733; margin:32px;
  max-width:1000px; }
h1 { font-size:24px; margin:0 0 8px; } p.answer { font-size:17px; }
table { border-collapse:collapse; margin:16px 0; }
th, td { border-bottom:1px solid #dfe4ea; padding:6px 12px; text-align:right; }
th:first-child, td:first-child, th:nth-child(2), td:nth-child(2) { text-align:left; }
td.good { color:#2a7d4f; font-weight:600; } p.note { color:#5f6b7a; }
"""


def _num(x: Any, sign: bool = False) -> str:
    if not isinstance(x, (int, float)) or not math.isfinite(x):
        return "n/a"
    return f"{x:+.2f}" if sign else f"{x:.2f}"


def headroom_html(data: dict[str, Any]) -> str:
    """The page of one headroom study."""
    esc = html.escape
    rows = [("best rule", data["best_rule"]), ("best static mix", data["best_mix"])]
    rows += [("policy", p) for p in data["policies"]]
    rows += [("lookahead", data["lookahead"]), ("bound (clairvoyant)", data["bound"])]
    rows += [("rule", r) for r in data["rules"] if r["policy"] != data["best_rule"]["policy"]]
    body = []
    for role, e in rows:
        good = isinstance(e.get("gain_ci_low"), (int, float)) and e["gain_ci_low"] > 0
        cpu = e.get("cpu_ms_per_decision")
        gain = f"{_num(e['gain'], True)}"
        interval = f"[{_num(e['gain_ci_low'], True)}, {_num(e['gain_ci_high'], True)}]"
        if role == "best rule":  # the reference itself: no difference to state
            gain, interval = "reference", ""
        body.append(
            "<tr>"
            f"<td>{esc(role)}</td><td>{esc(str(e['policy']))}</td>"
            f"<td>{_num(e['gripping_rate'])}</td>"
            f"<td>[{_num(e['ci_low'])}, {_num(e['ci_high'])}]</td>"
            f"<td class='{'good' if good else ''}'>{gain}</td><td>{interval}</td>"
            f"<td>{'' if cpu is None else _num(cpu)}</td>"
            "</tr>"
        )
    seeds = data["seeds"]
    head = (
        "<tr><th>role</th><th>policy</th><th>G %</th><th>95 % CI</th>"
        "<th>gain over best rule, points</th><th>paired 95 % CI</th><th>CPU ms/decision</th></tr>"
    )
    return (
        "<!doctype html><html><head><meta charset='utf-8'>"
        f"<title>headroom: {esc(data['scenario'])}</title><style>{CSS}</style></head><body>"
        f"<h1>How much could smarter coordination gain on {esc(data['scenario'])}?</h1>"
        f"<p class='answer'>{esc(data['answer'])}</p>"
        f"<table>{head}{''.join(body)}</table>"
        f"<p class='note'>Seeds {seeds[0]}..{seeds[-1]} ({len(seeds)}), {data['duration']:g} s "
        f"runs, warm-up {data['warmup']:g} s, {esc(data['termination'])}, common random "
        f"numbers; gains are paired differences to the best rule. Note: {esc(data['note'])}.</p>"
        "</body></html>\n"
    )
