"""The what-if panel: drop-downs over a study's stored grid (each swept field and the rule)
that show the gripping rate with its interval (and the cost, where the study has one) of the
chosen combination. Self-contained and offline: the rows are embedded as JSON and a few
lines of plain JavaScript look them up; nothing is simulated, a combination the study did
not run says so."""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from typing import Any

from pnp_twin.reports.html import esc
from pnp_twin.reports.text import fmt_value, param_label

SCRIPT = """
(function () {
  var root = document.getElementById('%(id)s');
  var data = JSON.parse(root.querySelector('script[type="application/json"]').textContent);
  var selects = Array.prototype.slice.call(root.querySelectorAll('select'));
  var out = root.querySelector('output');
  function bound(x) {  // never rounded across the target: 94.99 against 95 is not '95.0'
    var d = 1, t = data.target;
    while (t !== null && d < 4 && ((+x.toFixed(d) >= t) !== (x >= t))) { d += 1; }
    return x.toFixed(d);
  }
  function show() {
    var want = selects.map(function (s) { return s.value; }).join('|');
    var row = data.rows.find(function (r) { return r.key === want; });
    if (!row) { out.textContent = 'This combination was not run in the study.'; return; }
    var text = 'G = ' + row.mean.toFixed(1) + ' %%';
    text += row.low === null ? ' (' + (row.why || 'no interval') + ')' :
      ' (' + data.level + ' CI ' + bound(row.low) + ' to ' + bound(row.high) + ' %%)';
    if (row.cost !== null) { text += ' · total cost ' + Math.round(row.cost).toLocaleString('en'); }
    else if (data.nocost) { text += ' · ' + data.nocost; }
    if (row.note) { text += ' · ' + row.note; }
    out.textContent = text;
  }
  selects.forEach(function (s) { s.addEventListener('change', show); });
  show();
})();
"""


def _num(v: Any) -> float | None:
    try:
        x = float(v)
    except (TypeError, ValueError):
        return None
    return x if math.isfinite(x) else None


def _order(text: str) -> tuple[int, float, str]:
    """Numbers first, by value; then words."""
    x = _num(text)
    return (0, x, "") if x is not None else (1, 0.0, text)


def _combo_label(keys: Sequence[str], key: str) -> str:
    cells = key.split("|")
    return " · ".join(
        c if k == "policy" else f"{param_label(k, unit=False)} {c}"
        for k, c in zip(keys, cells, strict=True)
    )


def whatif_html(
    paths: Sequence[str],
    rows: Sequence[dict[str, Any]],
    level: str = "95 %",
    start: dict[str, Any] | None = None,
    panel_id: str = "whatif-panel",
    no_cost: str = "",
    target: float | None = None,
) -> str:
    """The panel: ``rows`` are {values: {path: value}, policy, mean, low, high, cost?,
    note?, why? (said instead of the interval when low is None)}; ``start`` the combination
    shown first (else the first row's); ``no_cost`` what a row without a cost says (e.g.
    "no cost file")."""
    if not rows:
        return ""
    keys = [*paths, "policy"]
    options: dict[str, list[str]] = {k: [] for k in keys}
    data = []
    for r in rows:
        cells = [fmt_value(r["values"][p]) for p in paths] + [str(r["policy"])]
        for k, c in zip(keys, cells, strict=True):
            if c not in options[k]:
                options[k].append(c)
        data.append(
            {
                "key": "|".join(cells),
                "mean": _num(r["mean"]) or 0.0,
                "low": _num(r.get("low")),
                "high": _num(r.get("high")),
                "cost": _num(r.get("cost")),
                "note": r.get("note") or "",
                "why": r.get("why") or "",
            }
        )
    for k in keys:  # each drop-down in axis order (numbers as numbers)
        options[k].sort(key=_order)
    first = start or {**rows[0]["values"], "policy": rows[0]["policy"]}
    controls = []
    if math.prod(len(v) for v in options.values()) > len(data):
        # sparse (a continuous range: few of the crossed values were run together): one
        # drop-down of the combinations that were run, sorted, instead of offering the rest
        names = sorted(
            ((str(d["key"]), _combo_label(keys, str(d["key"]))) for d in data),
            key=lambda kv: [_order(c) for c in kv[0].split("|")],
        )
        chosen = "|".join([fmt_value(first.get(k)) for k in paths] + [str(first.get("policy"))])
        opts = "".join(
            f'<option value="{esc(key)}"{" selected" if key == chosen else ""}>{esc(name)}</option>'
            for key, name in names
        )
        controls.append(f"<label>Configuration run <select>{opts}</select></label>")
        keys = []
    for k in keys:
        label = "Rule" if k == "policy" else param_label(k)
        chosen = fmt_value(first.get(k)) if k != "policy" else str(first.get("policy"))
        opts = "".join(
            f'<option value="{esc(o)}"{" selected" if o == chosen else ""}>{esc(o)}</option>'
            for o in options[k]
        )
        controls.append(f"<label>{esc(label)} <select>{opts}</select></label>")
    payload = json.dumps({"rows": data, "level": level, "nocost": no_cost, "target": target})
    payload = payload.replace("</", "<\\/")
    return (
        "<style>.whatif .controls{display:flex;flex-wrap:wrap;gap:10px 22px;margin:6px 0 10px}"
        ".whatif select{margin-left:6px;padding:3px 6px;font:inherit}"
        ".whatif output{font-weight:600;font-size:1.05em}</style>"
        f'<div class="whatif" id="{panel_id}">'
        f'<div class="controls">{" ".join(controls)}</div>'
        f'<p class="answer-line"><output>–</output></p>'
        f'<script type="application/json">{payload}</script>'
        f"<script>{SCRIPT % {'id': panel_id}}</script></div>"
    )
