"""The look shared by every report figure: fonts, colours and the common layout."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
import plotly.graph_objects as go

FONT = "Inter, 'Segoe UI', Roboto, 'Helvetica Neue', Arial, sans-serif"


PALETTE = (
    "#1f4e79",
    "#e07b39",
    "#2a9d8f",
    "#c0392b",
    "#7b5ea7",
    "#8c6d31",
    "#d45087",
    "#5c7080",
)


STATE_COLORS = {
    "busy": "#2a9d8f",
    "noop": "#e9c46a",
    "wait": "#f4a261",
    "blocked": "#8d99ae",
    "down": "#e63946",
    "interrupted": "#7b5ea7",
}


STATE_LABELS = {
    "busy": "Busy (move, grip, place)",
    "noop": "NooP (no candidate)",
    "wait": "Waiting (synchronous epoch)",
    "blocked": "Blocked (box change)",
    "down": "Down (breakdown)",
    "interrupted": "Interrupted approach",
}


PART_COLORS = {
    "to be picked": "#1f4e79",
    "claimed": "#2a9d8f",
    "will be missed": "#e63946",
    "passed on by design": "#a3acb9",  # a kind no robot picks
}


def policy_colors(policies: Sequence[str]) -> dict[str, str]:
    """One stable colour per policy, in the study's order."""
    return {p: PALETTE[i % len(PALETTE)] for i, p in enumerate(policies)}


def rgba(hex_color: str, alpha: float) -> str:
    """'#1f4e79', 0.2 -> 'rgba(31,78,121,0.2)'."""
    h = hex_color.lstrip("#")
    r, g, b = (int(h[i : i + 2], 16) for i in (0, 2, 4))
    return f"rgba({r},{g},{b},{alpha})"


def style(
    fig: go.Figure, title: str, subtitle: str = "", height: int = 420, top: int = 0
) -> go.Figure:
    """The house look: white template, system fonts, title with a grey subtitle."""
    text = f"<b>{title}</b>"
    lines = wrap_caption(subtitle) if subtitle else []
    for line in lines:  # a long caption wraps: a printed page is narrower than a screen
        text += f"<br><span style='font-size:12px;color:#5f6b7a'>{line}</span>"
    if len(lines) > 1:
        top = max(top, 60 + 18 * len(lines))
    fig.update_layout(
        template="plotly_white",
        title={"text": text, "x": 0.0, "xanchor": "left", "font": {"size": 16}},
        font={"family": FONT, "size": 12, "color": "#1d2733"},
        height=height,
        margin={"l": 70, "r": 30, "t": top or (80 if subtitle else 60), "b": 60},
        legend={"orientation": "h", "yanchor": "bottom", "y": 1.0, "xanchor": "right", "x": 1},
        hoverlabel={"font": {"family": FONT}},
    )
    return fig


CAPTION_WIDTH = 92  # characters of 12 px text that fit across a figure printed on A4


def wrap_caption(text: str, width: int = CAPTION_WIDTH) -> list[str]:
    """``text`` in lines of at most ``width`` characters, broken after ' · ', '; ' or ', '
    where it can (else between words), so a printed figure never cuts its caption."""
    if len(text) <= width:
        return [text]
    for sep in (" · ", "; ", ", ", " "):
        pieces = text.split(sep)
        if len(pieces) < 2:
            continue
        lines, line = [], pieces[0]
        for piece in pieces[1:]:
            if len(line) + len(sep) + len(piece) <= width:
                line += sep + piece
            else:
                lines.append(line + sep.rstrip())
                line = piece
        lines.append(line)
        if all(len(x) <= width for x in lines) or sep == " ":
            return lines
    return [text]


def cap_percent(fig: go.Figure, lows: Sequence[Any], highs: Sequence[Any]) -> None:
    """Fit a gripping-rate axis to the data but stop it at 100 %: a t-interval of few
    replications can reach past it, but no line can pick more parts than it is given."""

    def finite(xs: Sequence[Any]) -> list[float]:
        return [float(v) for v in xs if v is not None and np.isfinite(float(v))]

    lo, hi = finite(lows), finite(highs)
    if not lo or not hi:
        return
    pad = max(2.0, 0.06 * (max(hi) - min(lo)))
    fig.update_yaxes(range=[max(0.0, min(lo) - pad), min(101.0, max(hi) + pad)])
