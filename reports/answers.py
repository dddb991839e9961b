"""The answer each report opens with, in one sentence a plant engineer can forward: the
sweep's best policy where it matters, the sizing answer with its CI and the rule of thumb,
the best rule mix and its paired margin (or that the two best cannot be told apart), and the
precision an ``auto`` replication study reached."""

from __future__ import annotations

import math
from typing import Any

from pnp_twin.reports.load import Study
from pnp_twin.reports.text import (
    at_point,
    fmt_pct,
    fmt_value,
    point_text,
    reference_point,
    scenario_value,
    sizing_rows,
)


def fmt_ci(low: Any, high: Any, digits: int = 1, unit: str = " %") -> str:
    """'95 % CI 71.2 to 72.9 %'; empty when the interval is unknown (one replication)."""
    try:
        lo, hi = float(low), float(high)
    except (TypeError, ValueError):
        return ""
    if not (math.isfinite(lo) and math.isfinite(hi)):
        return ""
    return f"95 % CI {lo:.{digits}f} to {hi:.{digits}f}{unit}"


def _with_ci(mean: float, low: Any, high: Any) -> str:
    ci = fmt_ci(low, high)
    return fmt_pct(mean) + (f" ({ci})" if ci else "")


def sweep_headline(study: Study) -> str:
    """The sweep's answer in one sentence: the best policy, at the base line and the hardest
    point (the lowest best gripping rate)."""
    best, s, grid = study.best, study.summary, list(study.grid)
    if best is None or best.empty:
        return "The study has no results."
    wins = best["policy"].value_counts()
    leader = str(wins.index[0])
    share = f"at {int(wins.iloc[0])} of {len(best)} grid points" if len(best) > 1 else ""

    def g_at(point: dict[str, Any]) -> str:
        rows = at_point(s, point)
        row = rows[rows["policy"] == leader]
        if row.empty:
            return "–"
        r = row.iloc[0]
        return _with_ci(
            r["gripping_rate_mean"], r.get("gripping_rate_ci_low"), r.get("gripping_rate_ci_high")
        )

    if not grid:
        return f"{leader} is the best policy: {g_at({})}" + _lead_margin(study, {}, leader) + "."
    ref = reference_point(study)
    scenario = study.meta.get("scenario") or {}
    own = all(scenario_value(scenario, p) == v for p, v in ref.items())
    where = "the base line" if own else "the middle of the grid"
    hard = best.loc[best["gripping_rate_mean"].idxmin()]
    hard_point = {p: hard[p] for p in grid}
    out = f"{leader} is the best policy {share}".rstrip()
    out += f": at {where} ({point_text(ref, grid)}) it grips {g_at(ref)}"
    out += _lead_margin(study, ref, leader)
    if hard_point != ref:
        out += f"; at the hardest point ({point_text(hard_point, grid)}) {g_at(hard_point)}"
        if str(hard["policy"]) != leader:
            out += f", where {hard['policy']} is best with {fmt_pct(hard['gripping_rate_mean'])}"
    return out + "."


def _lead_margin(study: Study, point: dict[str, Any], leader: str) -> str:
    """', 1.2 points (paired 95 % CI 0.8 to 1.6) ahead of SD' at one point."""
    paired = study.paired
    if paired is None or paired.empty:
        return ""
    rows = at_point(paired, point)
    rows = rows[rows["policy"] != leader]
    if rows.empty:
        return ""
    r = rows.loc[rows["diff_mean"].idxmax()]
    gap, lo, hi = -float(r["diff_mean"]), -float(r["diff_ci_high"]), -float(r["diff_ci_low"])
    ci = fmt_ci(lo, hi, 2, "")
    if math.isfinite(lo) and lo <= 0:
        return f", but it cannot be told apart from {r['policy']} ({gap:+.2f} points, paired {ci})"
    return f", {gap:.2f} points ahead of {r['policy']}" + (f" (paired {ci})" if ci else "")


def size_headline(sizing: dict[str, Any]) -> str:
    """'N robots (G with its CI); rule of thumb M' in one sentence."""
    target = float(sizing.get("target") or math.nan)
    conf = float(sizing.get("confidence") or 0.95)
    thumb = (sizing.get("rule_of_thumb") or {}).get("n_recommended")
    rot = f"; the rule of thumb says {thumb}" if thumb is not None else ""
    answer = sizing.get("answer")
    rows = [r for r in sizing_rows(sizing) if r["condition"] in ("", "no breakdowns")]
    if answer is None:
        top = max(rows, key=lambda r: r["mean"] if r["mean"] is not None else -1, default=None)
        best = ""
        if top is not None:
            g = _with_ci(top["mean"], top["ci_low"], top["ci_high"])
            best = f" (best: {fmt_value(top['value'])} robots, {g})"
        return (
            f"No robot count tried reaches G ≥ {target:g} % with {conf * 100:g} % confidence"
            f"{best}{rot}."
        )
    row = next((r for r in rows if r["value"] == answer), None)
    g = f": G = {_with_ci(row['mean'], row['ci_low'], row['ci_high'])}" if row else ""
    return (
        f"{fmt_value(answer)} robots reach G ≥ {target:g} % with {conf * 100:g} % confidence"
        f"{g}{rot}."
    )


def mix_headline(mix: dict[str, Any]) -> str:
    """The best mix and its paired margin over the runner-up, or that they are a tie."""
    ranked = mix.get("ranked") or []
    if not ranked:
        return "The rule-mix search ranked no mix."
    top = ranked[0]
    out = (
        f"Best rule mix: {top['mix']} (robot 1 first), G = "
        f"{_with_ci(float(top['gripping_rate_mean']), top.get('ci_low'), top.get('ci_high'))}"
    )
    m = mix.get("margin")
    if not m or len(ranked) < 2:
        return out + "."
    ci = fmt_ci(m.get("ci_low"), m.get("ci_high"), 2, "")
    gap = float(m["diff_mean"])
    if m.get("distinguishable"):
        return out + f"; {gap:.2f} points ahead of {m['runner_up']} (paired {ci})."
    why = f"paired {ci}" if ci else "one replication gives no interval"
    return (
        out + f"; it cannot be told apart from {m['runner_up']} ({gap:+.2f} points, {why}): "
        "either mix will do, or run more replications to separate them."
    )


def headline(study: Study) -> str:
    """The report's answer in one sentence, by study kind."""
    if study.sizing is not None:
        return size_headline(study.sizing)
    if study.mix is not None:
        return mix_headline(study.mix)
    return sweep_headline(study)


def precision_text(meta: dict[str, Any]) -> str:
    """The precision a ``replications = "auto"`` study reached, in one sentence ('' without)."""
    p = meta.get("precision")
    if not isinstance(p, dict) or not p:
        return ""
    conf = 100 * float(p.get("confidence") or 0.95)
    target = float(p.get("target_half_width") or math.nan)
    rounds = " → ".join(str(r) for r in p.get("rounds") or [])
    widest = float(p.get("half_width_max") or math.nan)
    head = f"Replications chosen for precision ({rounds} in rounds): "
    if p.get("reached"):
        return head + (
            f"every point's {conf:g} % CI of G is at most ± {target:g} points "
            f"(widest ± {widest:.2f})."
        )
    return head + (
        f"{p.get('points_short')} point(s) still have a {conf:g} % CI of G wider than "
        f"± {target:g} points (widest ± {widest:.2f}) at the maximum of "
        f"{p.get('max_replications')} replications; read those with care."
    )
