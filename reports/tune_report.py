"""The tune study's page: the line to type into the controller, how sure it is, and the
comparison on the same seeds (no scripts, opens offline).

A pure function from the study's JSON (:meth:`pnp_twin.studies.tune.Tuned.to_json`) and its
trials table to one HTML string.
"""

from __future__ import annotations

import html
import math
from collections.abc import Sequence
from typing import Any

from pnp_twin.reports.headroom_report import CSS


def _num(x: Any) -> str:
    if not isinstance(x, int | float) or not math.isfinite(x):
        return "n/a"
    return f"{x:.2f}"


def tune_html(data: dict[str, Any], trials: Sequence[dict[str, Any]]) -> str:
    """The page of one tune study."""
    esc = html.escape
    rows = [
        ("tuned " + data["strategy"], data["tuned"]),
        ("best rule", data["best_rule"]),
        ("lookahead", data["lookahead"]),
    ]
    body = "".join(
        f"<tr><td>{esc(role)}</td><td>{esc(str(e['policy']))}</td>"
        f"<td>{_num(e['gripping_rate'])}</td><td>[{_num(e['ci_low'])}, {_num(e['ci_high'])}]"
        f"</td><td>{_num(e['passed_on'])}</td></tr>"
        for role, e in rows
    )
    best = sorted(trials, key=lambda t: -float(t["objective"]))[:10]
    tried = "".join(
        f"<tr><td>{int(t['trial'])}</td><td>{esc(str(t['policy']))}</td>"
        f"<td>{_num(t['gripping_rate'])}</td><td>{_num(t['passed_on'])}</td></tr>"
        for t in best
    )
    seeds, tuning = data["seeds"], data["tuning_seeds"]
    target = "" if data["target"] is None else f" with a target of {data['target']:g} %"
    return (
        "<!doctype html><html><head><meta charset='utf-8'>"
        f"<title>tune: {esc(data['scenario'])}</title><style>{CSS}</style></head><body>"
        f"<h1>{esc(data['strategy'].capitalize())} balancing for {esc(data['scenario'])}</h1>"
        f"<p class='answer'>{esc(data['answer'])}</p>"
        "<table><tr><th>role</th><th>policy</th><th>G %</th><th>95 % CI</th>"
        f"<th>parts passed on per run (summed over robots)</th></tr>{body}</table>"
        f"<p class='note'>Chosen from {data['trials']} settings{esc(target)} on tuning seeds "
        f"{tuning[0]}..{tuning[-1]}; G and its interval are from seeds {seeds[0]}..{seeds[-1]} "
        f"({len(seeds)}), which played no part in the choice, so the interval holds after the "
        f"selection. {data['duration']:g} s runs, warm-up {data['warmup']:g} s, "
        f"{esc(data['termination'])}; common random numbers: every policy saw the same "
        "parts.</p>"
        "<h2>The best settings tried (tuning seeds)</h2>"
        "<table><tr><th>trial</th><th>policy</th><th>G %</th><th>parts passed on</th></tr>"
        f"{tried}</table></body></html>\n"
    )
