"""The replay as a block of a report: a canvas per run, shared controls, the data and the
player (``replay.js``, inlined), so the page stays self-contained and opens offline.

:func:`replay_html` takes one or two :func:`reports.replay_data.replay_data` dicts (two: the
same seed under two policies, drawn in step, ``pnp-twin compare``).
"""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from importlib import resources
from typing import Any

from pnp_twin.reports.html import esc
from pnp_twin.reports.replay_data import FATES

SPEEDS = (1, 2, 5, 10, 20, 50)
DEFAULT_SPEED = 5

CSS = """
.replay { margin:10px 0 18px; }
.replay .rp-controls { display:flex; flex-wrap:wrap; align-items:center; gap:10px;
  margin:6px 0 8px; font-size:13.5px; }
.replay button { font:inherit; border:1px solid var(--line); background:#fff;
  border-radius:6px; padding:4px 12px; cursor:pointer; color:var(--ink); }
.replay button:hover { border-color:var(--brand); color:var(--brand); }
.replay .rp-scrub { flex:1 1 260px; accent-color:var(--brand); }
.replay .rp-clock { font-variant-numeric:tabular-nums; min-width:90px; font-weight:600; }
.replay .rp-diff { font-weight:600; color:var(--brand); }
.replay .rp-lane h3 { margin:8px 0 4px; font-size:14.5px; }
.replay .rp-lane h3 .rp-g { color:var(--muted); font-weight:500; margin-left:10px; }
.replay canvas { width:100%; display:block; border:1px solid var(--line); border-radius:8px; }
.replay .rp-legend { color:var(--muted); font-size:12.5px; margin-top:6px; }
.replay .rp-legend i { display:inline-block; width:10px; height:10px; border-radius:50%;
  margin:0 4px 0 10px; vertical-align:-1px; border:2px solid; }
@media print { .replay .rp-controls { display:none; } }
"""


def player_js() -> str:
    """The player, as shipped beside this module."""
    return resources.files("pnp_twin.reports").joinpath("replay.js").read_text("utf-8")


def _legend(data: Mapping[str, Any]) -> str:
    kinds = [
        f'<i style="background:{c};border-color:#1d2733"></i>{esc(k)}'
        for k, c in zip(data["kinds"], data["kindColours"], strict=True)
        if k
    ]
    fates = [
        '<i style="background:#fff;border-color:#1d2733"></i>on the belt',
        '<i style="background:#fff;border-color:#1f4e79"></i>claimed (ring: its robot)',
        '<i style="background:#fff;border-color:#e63946"></i>will be lost',
    ]
    if any(f == FATES.index("by design") for f in data["parts"]["fate"]):
        fates.append('<i style="background:#fff;border-color:#a3acb9"></i>passed on by design')
    text = "Fill: " + " ".join(kinds) + " · " if kinds else ""
    text += "Ring: " + " ".join(fates)
    text += " · Square: a robot's tool, joined to its base; a line joins it to the part it "
    text += "is going for. Yellow bin: a box change; a grey tool with a red cross: a breakdown."
    return f'<p class="rp-legend">{text}</p>'


def replay_html(datas: Sequence[Mapping[str, Any]], element_id: str = "replay") -> str:
    """The replay block of one run, or of two in step (the first is the reference)."""
    if not 1 <= len(datas) <= 2:
        raise ValueError("a replay draws one run or two in step")
    speeds = "".join(
        f'<option value="{s}"{" selected" if s == DEFAULT_SPEED else ""}>{s}×</option>'
        for s in SPEEDS
    )
    lanes = "".join(
        f'<div class="rp-lane"><h3>{esc(d.get("title") or "")}<span class="rp-g"></span>'
        "</h3><canvas></canvas></div>"
        for d in datas
    )
    payload = json.dumps(list(datas), separators=(",", ":"), allow_nan=False)
    payload = payload.replace("</", "<\\/")
    diff = '<span class="rp-diff"></span>' if len(datas) == 2 else ""
    return (
        f"<style>{CSS}</style>"
        f'<div class="replay" id="{esc(element_id)}" data-replay>'
        '<div class="rp-controls"><button class="rp-play" type="button">▶ Play</button>'
        f'<label>Speed <select class="rp-speed">{speeds}</select></label>'
        '<input class="rp-scrub" type="range" aria-label="time">'
        '<span class="rp-clock"></span>'
        '<button class="rp-lost" type="button">Next lost part »</button>'
        f"{diff}</div>{lanes}{_legend(datas[0])}"
        f'<script type="application/json" class="rp-data">{payload}</script>'
        f"<script>{player_js()}</script></div>"
    )


def replay_intro(data: Mapping[str, Any]) -> str:
    """One line over the replay: which stretch of the run it shows."""
    return esc(
        f"The run as it was simulated, from t = {data['t0']:g} s to {data['t1']:g} s, drawn "
        "from its own records (parts and robot states). Play it, change the speed, drag the "
        "time or jump to the next part the line loses."
    )
