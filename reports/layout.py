"""What goes on the page for one study: the sections, in reading order, each with only the
figures the study's tables can fill (a study with one grid parameter, or none, or one
policy, or without records gets fewer sections, never an empty chart)."""

from __future__ import annotations

import math
from datetime import datetime
from typing import Any

import pandas as pd

from pnp_twin.reports import figures, record_figures, style, welch
from pnp_twin.reports.answers import (
    NO_INTERVAL,
    headline,
    one_trace,
    one_trace_at,
    precision_text,
)
from pnp_twin.reports.html import Page, Section, esc, table_html
from pnp_twin.reports.load import Study
from pnp_twin.reports.mix_ranking import mix_section
from pnp_twin.reports.replay_data import replay_data
from pnp_twin.reports.replay_page import replay_html
from pnp_twin.reports.text import (
    at_point,
    fmt_pct,
    fmt_pm,
    fmt_seconds,
    fmt_value,
    key_findings,
    param_label,
    param_value,
    point_label,
    reference_point,
    scenario_value,
    sizing_rows,
    sizing_text,
)
from pnp_twin.reports.whatif import whatif_html

TIMELINE_SECONDS = 20.0
MAX_POLICIES = 8  # one colour each in style.PALETTE
KINDS = {"sweep": "Parameter sweep", "size": "Sizing study", "mix": "Rule-mix search"}


def heatmap_axes(varying: list[str]) -> tuple[str, str, str | None] | None:
    """x, y and facet parameters: the paper's arm speed x part flow per belt speed when the
    grid has them, else the first varying parameters in the study's order."""
    if len(varying) < 2:
        return None
    preferred = ["robots.arm_speed", "feeder.rate", "belt.speed"]
    order = [p for p in preferred if p in varying] + [p for p in varying if p not in preferred]
    return order[0], order[1], order[2] if len(order) > 2 else None


def shown_policies(study: Study, limit: int = MAX_POLICIES) -> list[str]:
    """The policies the line charts draw: all of them, or the ``limit`` best by mean gripping
    rate over the grid (a mix search can rank hundreds), in the study's order."""
    policies = study.policies
    if len(policies) <= limit:
        return policies
    mean = study.summary.groupby("policy")["gripping_rate_mean"].mean()
    top = set(mean.sort_values(ascending=False).index[:limit])
    return [p for p in policies if p in top]


def showcase_point(study: Study) -> tuple[dict[str, Any], str]:
    """The grid point and policy the per-robot figures describe: the recommended line (a
    sizing study's answer, without breakdowns), else the recorded run's, else the reference
    point, with the best policy there."""
    grid = list(study.grid)
    results = study.results
    sizing = study.sizing or {}
    answer = next(
        (
            r
            for r in sizing.get("rows") or []
            if r.get("robots.count") == sizing.get("answer") and not r.get("robots.mtbf")
        ),
        None,
    )
    if answer is not None and grid and all(p in answer for p in grid):
        return {p: answer[p] for p in grid}, str(answer["policy"])
    if study.run is not None and results is not None and "point" in results.columns:
        rows = results[results["point"] == study.run.get("point")]
        if len(rows) and grid:
            return {p: rows.iloc[0][p] for p in grid}, str(study.run.get("policy"))
    point = reference_point(study)
    best = at_point(study.best, point) if study.best is not None else study.summary
    policy = str(best.iloc[0]["policy"]) if len(best) else study.policies[0]
    return point, policy


def sizing_cards(sizing: dict[str, Any], trace: bool = False) -> list[tuple[str, str, str]]:
    """A sizing study's headline numbers: what to buy and run, the promise (the lower
    confidence bound of G there, which is what the target is met with) and the count to
    plan with breakdowns (with the MTBF and MTTR it assumes)."""
    answer = sizing.get("answer")
    target = float(sizing.get("target") or math.nan)
    conf = 100 * float(sizing.get("confidence") or 0.95)
    rule = sizing.get("rule")
    row = next(
        (
            r
            for r in sizing_rows(sizing)
            if r["value"] == answer and r["condition"] in ("", "no breakdowns")
        ),
        None,
    )
    if answer is None:
        out = [("Sizing answer", "not reached", f"no count tried reaches G ≥ {fmt_pct(target)}")]
    else:
        out = [
            (
                "Buy",
                f"{fmt_value(answer)} robots",
                (f"running {rule} · " if rule else "") + f"for G ≥ {fmt_pct(target)}",
            )
        ]
        if row is not None and trace:
            out.append(("Promise", fmt_pct(row["mean"]), "one replayed trace: no interval"))
        elif row is not None and row["ci_low"] is not None:
            out.append(
                (
                    "Promise",
                    f"G ≥ {fmt_pct(float(row['ci_low']))}",
                    f"with {conf:g} % confidence (mean {fmt_pct(row['mean'])})",
                )
            )
    down = sizing.get("breakdown") or {}
    if down.get("mtbf") is not None:
        n = down.get("n_with_failures")
        out.append(
            (
                "With breakdowns",
                "not reached" if n is None else f"{fmt_value(n)} robots",
                f"MTBF {fmt_value(down['mtbf'])} s, MTTR {fmt_value(down.get('mttr'))} s"
                + (" (assumed)" if down.get("assumed") else ""),
            )
        )
    return out


def cards(study: Study) -> list[tuple[str, str, str]]:
    """The headline numbers under the title (a sizing study: its answer and promise first,
    not the best G of the largest line)."""
    s = study.summary
    if study.sizing is not None:
        out = sizing_cards(study.sizing, one_trace(study.meta))
    else:
        top = s.loc[s["gripping_rate_mean"].idxmax()]
        where = f" · {point_label(top, list(study.grid))}" if study.grid else ""
        best = fmt_pct(top["gripping_rate_mean"])
        out = [("Best gripping rate", best, f"{top['policy']}{where}")]
    points = len(study.best) if study.best is not None else 1
    if study.varying:
        out.append(("Grid points", str(points), f"{len(study.varying)} parameter(s) varied"))
    if study.mix is not None:
        method = study.mix.get("method", "search")
        out.append(("Mixes", str(len(study.policies)), f"{method} search, ranked below"))
    else:
        out.append(("Policies", str(len(study.policies)), shorten(", ".join(study.policies), 60)))
    runs = len(study.results) if study.results is not None else int(s.get("n", pd.Series()).sum())
    reps = study.meta.get("replications")
    out.append(("Runs", f"{runs:,}", f"{reps} replications each" if reps else ""))
    wall = study.meta.get("wall_time")
    workers = study.meta.get("workers")
    out.append(
        (
            "Run time",
            fmt_seconds(float(wall)) if wall is not None else "–",
            f"{workers} worker(s), {study.meta.get('backend', 'local')}" if workers else "",
        )
    )
    return out


def shorten(text: str, limit: int) -> str:
    """``text`` cut at the last ', ' (else space) before ``limit`` characters, with '…';
    never in the middle of a name."""
    if len(text) <= limit:
        return text
    cut = text.rfind(", ", 0, limit)
    cut = cut if cut > 0 else text.rfind(" ", 0, limit)
    return (text[:cut] if cut > 0 else text.split(" ")[0]) + " …"


def when_text(stamp: Any) -> str:
    """'2025-01-01T10:00:05Z' -> '2025-01-01 10:00:05 UTC'; anything else as it is."""
    if not stamp:
        return "–"
    try:
        t = datetime.fromisoformat(str(stamp))
    except ValueError:
        return str(stamp)
    zone = " UTC" if t.utcoffset() is not None and not t.utcoffset() else ""
    return t.strftime("%Y-%m-%d %H:%M:%S") + zone


def facts(study: Study) -> str:
    """'What was run' as a two-column table."""
    m = study.meta
    scenario = m.get("scenario") or {}
    rows: list[tuple[str, str]] = [
        ("Scenario", f"<b>{esc(study.scenario_name)}</b> — {esc(scenario.get('description', ''))}"),
        ("Study", esc(KINDS.get(str(m.get("kind")), str(m.get("kind", "–"))))),
    ]
    for path, values in study.grid.items():
        rows.append((esc(param_label(path)), esc(", ".join(fmt_value(v) for v in values))))
    if study.mix is not None and len(study.policies) > 12:
        n = len(study.policies)
        rows.append(("Policies", esc(f"{n} rule mixes, ranked in the table above")))
    else:
        rows.append(("Policies", esc(", ".join(study.policies))))
    line = [
        f"{scenario_value(scenario, 'robots.count')} robots",
        f"arm {fmt_value(scenario_value(scenario, 'robots.arm_speed'))} m/s",
        f"belt {fmt_value(scenario_value(scenario, 'belt.speed'))} m/s",
        flow_text(study),
        f"termination {scenario_value(scenario, 'termination')}",
    ]
    if scenario:
        rows.append(("Base line", esc(" · ".join(line))))
    seeds = ""
    if study.results is not None and "seed" in study.results.columns:
        found = sorted(pd.unique(study.results["seed"]).tolist())
        shown = ", ".join(str(x) for x in found[:6]) + (" …" if len(found) > 6 else "")
        seeds = f"; run seeds {shown}"
    rows.append(
        (
            "Replications",
            esc(
                f"{m.get('replications', '–')} per point and policy, common random numbers "
                f"(master seed {m.get('master_seed', '–')}{seeds})"
            ),
        )
    )
    rows.append(
        (
            "Simulated time",
            esc(
                f"{fmt_value(m.get('duration', '–'))} s per run, of which "
                f"{fmt_value(m.get('warmup', '–'))} s warm-up (not measured)"
            ),
        )
    )
    when = f"{when_text(m.get('started_at'))} → {when_text(m.get('finished_at'))}"
    wall = m.get("wall_time")
    if wall is not None:
        when += f" ({fmt_seconds(float(wall))}, {m.get('workers', '?')} worker(s), "
        when += f"{m.get('backend', 'local')} backend)"
    rows.append(("Run", esc(when)))
    if m.get("command"):
        rows.append(("Command", f"<code>{esc(m['command'])}</code>"))
    versions = m.get("versions") or {}
    if versions:
        rows.append(("Versions", esc(" · ".join(f"{k} {v}" for k, v in versions.items()))))
    body = "".join(f"<tr><th>{k}</th><td>{v}</td></tr>" for k, v in rows)
    return f'<table class="facts"><tbody>{body}</tbody></table>'


def flow_text(study: Study) -> str:
    """The base line's part flow: '10 parts/s (poisson)', or for a replayed trace its real
    mean rate ('7.17 parts/s mean of the trace sample.csv'), never the unused feeder.rate."""
    scenario = study.meta.get("scenario") or {}
    arrival = scenario_value(scenario, "feeder.arrival")
    if arrival != "trace":
        return f"{fmt_value(scenario_value(scenario, 'feeder.rate'))} parts/s ({arrival})"
    info = study.meta.get("trace") or {}
    rate = info.get("mean_rate")
    name = info.get("file") or str(scenario_value(scenario, "feeder.trace") or "")
    if rate is None and study.results is not None and "part_flow" in study.results.columns:
        rate = float(study.results["part_flow"].mean())  # what the runs were fed
    shown = f"{float(rate):.3g} parts/s" if rate is not None else "the rate"
    files = info.get("files") or []
    if len(files) > 1:  # replication k replays trace k
        listed = ", ".join(files[:3]) + (", ..." if len(files) > 3 else "")
        return f"{shown} mean of the {len(files)} replayed traces ({listed}), one per replication"
    return f"{shown} mean of the replayed trace {name}".rstrip()


def kpi_table(study: Study) -> str:
    """Mean KPIs with 95 % CI per grid point and policy; the best policy's row highlighted."""
    s = study.summary
    grid = list(study.grid)
    order = {p: i for i, p in enumerate(study.policies)}
    s = s.assign(_o=s["policy"].map(order)).sort_values([*grid, "_o"])
    best = study.best
    winners = {
        tuple(r[p] for p in grid): r["policy"]
        for _, r in (best if best is not None else s).iterrows()
    }

    trace = one_trace(study.meta)

    def cell(row: pd.Series, kpi: str, scale: float, digits: int, unit: str = "") -> str:
        mean = row.get(f"{kpi}_mean", math.nan) * scale
        if not math.isfinite(mean):
            return "–"
        if trace:  # one replayed trace is one sample: no interval
            return f"{mean:.{digits}f}{unit}"
        if one_trace_at(study.meta, {p: row[p] for p in grid}):  # the trace point of a grid
            note = f'<span class="pm">{esc(NO_INTERVAL)}</span>' if kpi == "gripping_rate" else ""
            return f"{mean:.{digits}f}{unit}{note}"
        pm = fmt_pm(
            row.get(f"{kpi}_ci_low", math.nan) * scale,
            row.get(f"{kpi}_ci_high", math.nan) * scale,
            digits,
        )
        return f'{mean:.{digits}f}{unit}<span class="pm">{esc(pm)}</span>'

    header = [esc(param_label(p)) for p in grid] + [
        "Policy",
        "Gripping rate",
        "Throughput (parts/s)",
        "Efficiency",
        "Utilisation",
        "n",
    ]
    rows, classes = [], []
    for _, r in s.iterrows():
        is_best = winners.get(tuple(r[p] for p in grid)) == r["policy"]
        rows.append(
            [esc(fmt_value(r[p])) for p in grid]
            + [
                esc(r["policy"]) + (" ★" if is_best and len(study.policies) > 1 else ""),
                cell(r, "gripping_rate", 1, 1, " %"),
                cell(r, "throughput", 1, 2),
                cell(r, "efficiency", 100, 1, " %"),
                cell(r, "utilisation", 100, 1, " %"),
                esc(int(r["n"])) if "n" in r and pd.notna(r["n"]) else "–",
            ]
        )
        classes.append("best" if is_best and len(study.policies) > 1 else "")
    return table_html(header, rows, left=0, classes=classes, scroll=len(rows) > 14)


def answer_section(study: Study) -> Section:
    """The answer in one sentence first; for a sizing study the reasoning, the chart and the
    layout the robots were given."""
    sentences = [headline(study)]
    if precision_text(study.meta):
        sentences.append(precision_text(study.meta))
    if one_trace(study.meta):
        sentences.append(
            "Every replication replays the same recorded trace, so together they are one "
            f"sample ({NO_INTERVAL}): replay several traces for an interval, or add --set "
            "feeder.arrival=poisson to see the same mean rate with random gaps."
        )
    if study.sizing is not None:
        sentences += sizing_text(study.sizing, one_trace(study.meta))[1:]
        layout = study.sizing.get("layout") or {}
        if layout:
            sentences.append(layout_sentence(study.sizing))
    body = "".join(f"<p>{esc(t)}</p>" for t in sentences)
    items: list[Any] = [f'<div class="answer">{body}</div>']
    if study.sizing is not None and study.sizing.get("rows"):
        items.append(figures.sizing_figure(study.sizing))
        if study.sizing.get("layout"):
            items.append(figures.layout_figure(study.sizing))
    return Section("answer", "The answer", "", items)


def layout_sentence(sizing: dict[str, Any]) -> str:
    """How the robots were laid out (extend the belt, or share it), as sizing.json says."""
    layout = sizing.get("layout") or {}
    return str(layout.get("text") or f"Layout: {layout.get('mode', 'extend')}.")


def whatif_section(study: Study) -> Section | None:
    """Drop-downs over the stored grid and the rules: G with its interval at any combination
    the study ran (nothing is simulated)."""
    grid = list(study.grid)
    if not grid and len(study.policies) < 2:
        return None
    s = study.summary
    best = study.best
    winners = {
        tuple(r[p] for p in grid): str(r["policy"])
        for _, r in (best if best is not None else s).iterrows()
    }
    costs = study.meta.get("costs") or {}
    cost_at = {
        (int(c["point"]), str(c["policy"])): c.get("total_cost") for c in costs.get("rows") or []
    }
    rows = []
    for _, r in s.iterrows():
        here = tuple(r[p] for p in grid)
        values = {p: r[p] for p in grid}
        trace = one_trace_at(study.meta, values)  # one replayed trace: one sample
        rows.append(
            {
                "values": values,
                "policy": r["policy"],
                "mean": r["gripping_rate_mean"],
                "low": None if trace else r.get("gripping_rate_ci_low"),
                "high": None if trace else r.get("gripping_rate_ci_high"),
                "why": NO_INTERVAL if trace else "",
                "cost": cost_at.get((int(r["point"]), str(r["policy"]))) if "point" in r else None,
                "note": "the best rule here"
                if len(study.policies) > 1 and winners.get(here) == r["policy"]
                else "",
            }
        )
    ref = reference_point(study)
    start = {**ref, "policy": winners.get(tuple(ref[p] for p in grid), study.policies[0])}
    conf = f"{100 * float(study.meta.get('confidence') or 0.95):g} %"
    panel = whatif_html(grid, rows, conf, start, no_cost="" if costs else "no cost file")
    what = "a value of each swept field and a rule" if grid else "a rule"
    if study.mix is not None:
        what = "a rule mix"
    intro = f"Choose {what}: the gripping rate the study measured there, with its confidence "
    intro += "interval"
    intro += f" and total cost priced from {costs.get('file')}" if costs else ""
    intro += ", from the stored runs (nothing is simulated)."
    return Section("whatif", "What if", esc(intro), [panel])


def sweep_section(study: Study) -> Section | None:
    if not study.varying:
        return None
    ref = reference_point(study)
    shown = shown_policies(study)
    colors = style.policy_colors(shown)
    items: list[Any] = []
    for path in study.varying:
        fixed = {k: v for k, v in ref.items() if k != path}
        items.append(figures.sweep_figure(study.summary, path, fixed, shown, colors))
    intro = "Mean gripping rate of each policy as one parameter varies, the others held at the "
    intro += "base scenario's values (or the middle of their range); shaded bands are 95 % CIs."
    if len(shown) < len(study.policies):
        intro += f" The {len(shown)} best of {len(study.policies)} policies are drawn."
    return Section("sweep", "Gripping rate against each parameter", esc(intro), items)


def heatmap_section(study: Study) -> Section | None:
    axes = heatmap_axes(study.varying)
    if axes is None or study.best is None:
        return None
    x, y, facet = axes
    ref = reference_point(study)
    fixed = {k: v for k, v in ref.items() if k not in (x, y, facet)}
    fig = figures.heatmap_figure(study.best, x, y, facet, fixed)
    intro = "Mean gripping rate of the best policy in each cell (the winning policy is named)"
    intro += f", one panel per {param_label(facet, False).lower()}." if facet else "."
    return Section("heatmaps", "Heatmaps", esc(intro), [fig])


def policy_section(study: Study) -> Section | None:
    paired = study.paired
    if len(study.policies) < 2 or paired is None or paired.empty:
        return None
    shown = shown_policies(study)
    colors = style.policy_colors(shown)
    fig = figures.policy_figure(paired, list(study.grid), shown, colors)
    intro = "Each policy's gripping rate minus the best policy's at the same grid point, paired by "
    intro += "replication. An error bar that crosses zero means the data cannot tell the two apart."
    if len(shown) < len(study.policies):
        intro += f" The {len(shown)} best of {len(study.policies)} policies are drawn."
    return Section("policies", "Policy comparison", esc(intro), [fig])


def robots_section(study: Study) -> Section | None:
    results = study.results
    if results is None or record_figures.robot_count(results) == 0:
        return None
    if "r1_passed_on" not in results.columns:  # a folder written before passed on / lost
        return None
    point, policy = showcase_point(study)
    runs = at_point(results, point)
    if runs[runs["policy"] == policy].empty:
        return None
    fig = record_figures.robots_figure(results, point, policy)
    intro = "Where each robot's time goes, and what becomes of the parts it leaves: passed on "
    intro += "(picked by a robot downstream) or lost (to the return conveyor)."
    if study.sizing is not None or study.mix is not None:
        intro += " The line shown is the recommended one."
    return Section("robots", "Robots", esc(intro), [fig])


def welch_section(study: Study) -> Section | None:
    """Welch's warm-up plot of the recommended configuration's replications."""
    results = study.results
    if results is None or welch.COLUMN not in results.columns:
        return None
    point, policy = showcase_point(study)
    runs = at_point(results, point)
    runs = runs[runs["policy"] == policy]
    duration = float(study.meta.get("duration") or 0.0)
    warmup = float(study.meta.get("warmup") or 0.0)
    where = f"{policy}" + (f" at {point_label(point, list(point))}" if point else "")
    got = welch.welch_items(runs, duration, warmup, where)
    if got is None:
        return None
    fig, text, drifting = got
    box = f'<div class="{"warn" if drifting else "answer"}"><p>{esc(text)}</p></div>'
    intro = "Is the warm-up long enough? The gripping rate over time, averaged over the "
    intro += "replications and smoothed (Welch's method): the curve should be flat after the "
    intro += "dashed marker."
    return Section("warmup", "Warm-up", esc(intro), [box, fig])


def records_section(
    study: Study, animation: record_figures.Animation | None = None
) -> Section | None:
    animation = animation or record_figures.Animation()
    if study.parts is None or study.spans is None or study.run is None:
        return None
    scenario = study.run.get("scenario") or study.meta.get("scenario") or {}
    duration = float(scenario.get("duration") or study.meta.get("duration") or 60.0)
    warmup = float(scenario.get("warmup") or study.meta.get("warmup") or 0.0)
    t0 = warmup if duration - warmup >= 20 else max(0.0, duration - TIMELINE_SECONDS)
    t1 = min(t0 + TIMELINE_SECONDS, duration)
    n = int((scenario.get("robots") or {}).get("count") or 0) or int(
        max(study.spans["robot"].max(), study.parts["robot"].max())  # numbered from 1
    )
    items: list[Any] = []
    if t1 > t0:
        items.append(record_figures.timeline_figure(study.parts, study.spans, t0, t1, n))
    if len(study.parts):
        items.append(
            record_figures.animated_belt(study.parts, scenario, animation, warmup, duration)
        )
    if not items:
        return None
    run = study.run
    if len(study.parts):
        data = replay_data(
            study.parts,
            study.spans,
            scenario,
            run.get("seed"),
            animation.start,
            animation.seconds,
            f"{run.get('policy')}, seed {run.get('seed', '–')}",
        )
        items.insert(0, replay_html([data]))
    where = ""
    results = study.results
    if results is not None and "point" in results.columns and study.grid:
        rows = results[results["point"] == run.get("point")]
        if len(rows):
            values = [param_value(p, rows.iloc[0][p], lower=True) for p in study.grid]
            where = " at " + ", ".join(values)
    intro = (
        f"One recorded run: policy {run.get('policy')}{where}, replication "
        f"{run.get('replication', 0)}, seed {run.get('seed', '–')}."
    )
    return Section("run", "One run up close", esc(intro), items)


def build_page(study: Study, animation: record_figures.Animation | None = None) -> Page:
    """The report of ``study`` as a Page (sections in reading order); ``animation``: the
    stretch of the recorded run the belt animation covers (default a minute after warm-up)."""
    findings = "".join(f"<li>{esc(t)}</li>" for t in key_findings(study))
    notes = "".join(f'<p class="note">{esc(n)}</p>' for n in study.notes)
    summary = Section(
        "findings", "Key findings", "", [f'<ul class="findings">{findings}</ul>{notes}']
    )
    sections = [
        answer_section(study),
        mix_section(study),
        summary,
        Section("setup", "What was run", "", [facts(study)]),
        whatif_section(study),
        sweep_section(study),
        heatmap_section(study),
        policy_section(study),
        robots_section(study),
        records_section(study, animation),
        welch_section(study),
        Section(
            "kpis",
            "KPI summary",
            esc(
                "Mean over replications with the 95 % confidence half-width; ★ marks the best "
                "policy at each grid point. Efficiency: throughput over min(part flow, the "
                "robots' measured cycle rate, their picks per second of busy time), so a "
                "saturated line reads about 100 %; utilisation: share of time moving, gripping "
                "or placing. Gripping rate, efficiency and utilisation in %."
            ),
            [kpi_table(study)],
        ),
    ]
    kind = str(study.meta.get("kind", "study"))
    description = (study.meta.get("scenario") or {}).get("description") or ""
    finished = str(study.meta.get("finished_at") or "")[:10]
    versions = study.meta.get("versions") or {}
    lead = esc(description)
    if study.sizing is not None:  # the target this study used, whatever the description says
        conf = 100 * float(study.sizing.get("confidence") or 0.95)
        target = float(study.sizing.get("target") or math.nan)
        mode = (study.sizing.get("layout") or {}).get("mode", "extend")
        lead = esc(
            f"Target used: gripping rate ≥ {target:g} % with {conf:g} % confidence · layout "
            f"{mode} · scenario: {description}"
        )
    return Page(
        title=f"{study.scenario_name}: {KINDS.get(kind, kind).lower()}",
        eyebrow=f"pnp-twin report<span class='badge'>{esc(kind)}</span>",
        lead=lead + (f" · {esc(finished)}" if finished else ""),
        cards=cards(study),
        sections=[s for s in sections if s is not None],
        footer=esc(
            f"Generated by pnp-twin {versions.get('pnp_twin', '')} from {study.path.name}/ · "
            "self-contained: opens offline. Gripping rate G = parts picked / parts presented."
        ),
    )
