"""One self-contained HTML page: inline CSS, plotly.js inlined once, one div per figure.

Nothing on the page reaches the network (no CDN, no web fonts), so the file opens offline
and can be mailed as it is.
"""

from __future__ import annotations

import html
from collections.abc import Sequence
from dataclasses import dataclass, field

import plotly.graph_objects as go
from plotly.offline import get_plotlyjs

CONFIG = {
    "displaylogo": False,
    "responsive": True,
    "modeBarButtonsToRemove": ["lasso2d", "select2d"],
    "toImageButtonOptions": {"format": "png", "scale": 2},
}

CSS = """
:root { --ink:#1d2733; --muted:#5f6b7a; --line:#dfe4ea; --bg:#f5f7fa; --brand:#1f4e79;
  --good:#2a9d8f; --bad:#c0392b; }
* { box-sizing: border-box; }
body { margin:0; background:var(--bg); color:var(--ink);
  font:15px/1.55 Inter, "Segoe UI", Roboto, "Helvetica Neue", Arial, sans-serif; }
header.top { background:linear-gradient(120deg,#17324d,#1f4e79 60%,#2a6f97); color:#fff;
  padding:34px 0 30px; }
.wrap { max-width:1180px; margin:0 auto; padding:0 28px; }
header.top .eyebrow { text-transform:uppercase; letter-spacing:.12em; font-size:12px;
  opacity:.75; margin:0 0 6px; }
header.top h1 { margin:0; font-size:30px; font-weight:650; letter-spacing:-.01em; }
header.top p.lead { margin:8px 0 0; max-width:820px; opacity:.9; }
.cards { display:grid; grid-template-columns:repeat(auto-fit,minmax(170px,1fr)); gap:14px;
  margin:-22px auto 8px; position:relative; }
.card { background:#fff; border:1px solid var(--line); border-radius:10px; padding:14px 16px;
  box-shadow:0 2px 6px rgba(23,50,77,.06); }
.card .k { color:var(--muted); font-size:12px; text-transform:uppercase; letter-spacing:.06em; }
.card .v { font-size:24px; font-weight:650; margin-top:2px; font-variant-numeric:tabular-nums; }
.card .s { color:var(--muted); font-size:12.5px; }
nav.toc { margin:18px 0 0; font-size:13.5px; color:var(--muted); }
nav.toc a { color:var(--brand); text-decoration:none; margin-right:16px; white-space:nowrap; }
nav.toc a:hover { text-decoration:underline; }
section { background:#fff; border:1px solid var(--line); border-radius:12px;
  padding:22px 26px 18px; margin:22px 0; }
section h2 { margin:0 0 4px; font-size:20px; font-weight:650; }
section p.intro { margin:0 0 12px; color:var(--muted); max-width:900px; }
.answer { border-left:4px solid var(--good); background:#f0f8f7; padding:12px 16px;
  border-radius:0 8px 8px 0; margin:8px 0 14px; font-size:16px; }
.answer p { margin:4px 0; }
.warn { border-left:4px solid var(--bad); background:#fbefed; padding:12px 16px;
  border-radius:0 8px 8px 0; margin:8px 0 14px; }
.answer p:first-child { font-weight:600; }
ul.findings { margin:6px 0 4px; padding-left:20px; }
ul.findings li { margin:5px 0; }
.figure { margin:10px 0 18px; border-top:1px solid #eef1f4; padding-top:8px; }
.figure:first-of-type { border-top:none; }
table { border-collapse:collapse; width:100%; font-size:13.5px;
  font-variant-numeric:tabular-nums; }
th, td { padding:7px 10px; text-align:right; border-bottom:1px solid #edf0f3;
  white-space:nowrap; }
th { background:#f7f9fb; color:var(--muted); font-weight:600; font-size:12px;
  text-transform:uppercase; letter-spacing:.04em; position:sticky; top:0; z-index:1; }
td.l, th.l { text-align:left; }
tr.best td { background:#f0f8f7; }
tr.best td.pol { font-weight:650; }
td .pm { color:var(--muted); font-size:12px; margin-left:4px; }
.scroll { max-height:560px; overflow:auto; border:1px solid var(--line); border-radius:8px; }
table.facts th { position:static; text-align:left; width:210px; background:none;
  text-transform:none; letter-spacing:0; font-size:13.5px; vertical-align:top; }
table.facts td { text-align:left; white-space:normal; }
code { font-family:ui-monospace,SFMono-Regular,Menlo,Consolas,monospace; font-size:12.5px;
  background:#f1f3f6; padding:2px 6px; border-radius:4px; word-break:normal; }
.note { color:var(--muted); font-size:13px; font-style:italic; }
.badge { display:inline-block; background:rgba(255,255,255,.16); border-radius:999px;
  padding:2px 10px; font-size:12px; margin-left:10px; vertical-align:middle; }
footer { color:var(--muted); font-size:12.5px; padding:6px 0 40px; }
@media print {
  body { background:#fff; } section { border:none; padding:8px 0; }
  header.top { -webkit-print-color-adjust:exact; print-color-adjust:exact; }
  nav.toc, .modebar-container, .updatemenu-container, .slider-container { display:none; }
  /* every table row on paper: no scroll boxes, headers repeated on each page */
  .scroll { max-height:none !important; overflow:visible !important; border:none; }
  th { position:static; } thead { display:table-header-group; }
  tr, .figure, .answer, .card { break-inside:avoid; }
  td, th { white-space:normal; }
}
"""


@dataclass
class Section:
    """One block of the page: a heading, an intro line, then HTML snippets and figures."""

    id: str
    title: str
    intro: str = ""
    items: list[go.Figure | str] = field(default_factory=list)


@dataclass
class Page:
    """The whole report before rendering."""

    title: str
    eyebrow: str
    lead: str
    cards: list[tuple[str, str, str]]  # (label, value, small print)
    sections: list[Section]
    footer: str = ""

    @property
    def figures(self) -> int:
        return sum(isinstance(i, go.Figure) for s in self.sections for i in s.items)


def esc(text: object) -> str:
    """HTML-escaped text."""
    return html.escape(str(text), quote=True)


def figure_html(fig: go.Figure, div_id: str) -> str:
    """One figure as a div and its script, without plotly.js."""
    height = fig.layout.height or 420
    return fig.to_html(
        full_html=False,
        include_plotlyjs=False,
        config=CONFIG,
        auto_play=False,
        div_id=div_id,
        default_width="100%",
        default_height=f"{height}px",
    )


def table_html(
    header: Sequence[str],
    rows: Sequence[Sequence[str]],
    left: int = 0,
    classes: Sequence[str] | None = None,
    scroll: bool = False,
) -> str:
    """A table of already-escaped cells; the first ``left`` columns are left-aligned."""
    th = "".join(f'<th class="{"l" if i < left else ""}">{h}</th>' for i, h in enumerate(header))
    body = []
    for r, row in enumerate(rows):
        cls = f' class="{classes[r]}"' if classes and classes[r] else ""
        tds = "".join(f'<td class="{"l" if i < left else ""}">{c}</td>' for i, c in enumerate(row))
        body.append(f"<tr{cls}>{tds}</tr>")
    table = f"<table><thead><tr>{th}</tr></thead><tbody>{''.join(body)}</tbody></table>"
    return f'<div class="scroll">{table}</div>' if scroll else table


def render(page: Page) -> str:
    """The page as one HTML string; plotly.js appears exactly once, in the head."""
    cards = "".join(
        f'<div class="card"><div class="k">{esc(k)}</div><div class="v">{esc(v)}</div>'
        f'<div class="s">{esc(s)}</div></div>'
        for k, v, s in page.cards
    )
    toc = "".join(f'<a href="#{s.id}">{esc(s.title)}</a>' for s in page.sections)
    body = []
    n = 0
    for s in page.sections:
        parts = [f'<section id="{s.id}"><h2>{esc(s.title)}</h2>']
        if s.intro:
            parts.append(f'<p class="intro">{s.intro}</p>')
        for item in s.items:
            if isinstance(item, go.Figure):
                n += 1
                parts.append(f'<div class="figure">{figure_html(item, f"figure-{n}")}</div>')
            else:
                parts.append(item)
        parts.append("</section>")
        body.append("".join(parts))
    return f"""<!DOCTYPE html>
<html lang="en">
<head>
<meta charset="utf-8">
<meta name="viewport" content="width=device-width, initial-scale=1">
<meta name="generator" content="pnp-twin">
<meta name="pnp-twin-figures" content="{page.figures}">
<title>{esc(page.title)}</title>
<style>{CSS}</style>
<script type="text/javascript">{get_plotlyjs()}</script>
</head>
<body>
<header class="top"><div class="wrap">
<p class="eyebrow">{page.eyebrow}</p>
<h1>{esc(page.title)}</h1>
<p class="lead">{page.lead}</p>
</div></header>
<div class="wrap">
<div class="cards">{cards}</div>
<nav class="toc">{toc}</nav>
{"".join(body)}
<footer>{page.footer}</footer>
</div>
</body>
</html>
"""
