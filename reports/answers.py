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
from pnp_twin.twin.stats import t_interval

NO_INTERVAL = "one replayed trace: no interval"


def fmt_ci(low: Any, high: Any, digits: int = 1, unit: str = " %", confidence: float = 0.95) -> str:
    """'95 % CI 71.2 to 72.9 %'; empty when the interval is unknown (one replication)."""
    try:
        lo, hi = float(low), float(high)
    except (TypeError, ValueError):
        return ""
    if not (math.isfinite(lo) and math.isfinite(hi)):
        return ""
    return f"{100 * confidence:g} % CI {lo:.{digits}f} to {hi:.{digits}f}{unit}"


def one_trace(meta: dict[str, Any] | None) -> bool:
    """True when every run of the study replays the same recorded trace: its replications
    are one sample (their spread is zero), so no interval can be given."""
    scenario = (meta or {}).get("scenario") or {}
    grid = (meta or {}).get("grid") or {}
    feeder = scenario.get("feeder") or {}
    robots = scenario.get("robots") or {}
    random_failures = bool(robots.get("mtbf")) or any(grid.get("robots.mtbf") or [])
    swept = "feeder.trace" in grid or "feeder.arrival" in grid
    return (
        feeder.get("arrival") == "trace"
        and not swept
        and not random_failures
        and _trace_count(meta) == 1
    )


def _trace_count(meta: dict[str, Any] | None) -> int:
    """How many traces the study's replications replay (1 unless meta says more)."""
    try:
        return int(((meta or {}).get("trace") or {}).get("traces") or 1)
    except (TypeError, ValueError):
        return 1


def one_trace_at(meta: dict[str, Any] | None, values: dict[str, Any]) -> bool:
    """True when the runs at the grid point ``values`` all replay one recorded trace (the
    ``"trace"`` point of a study whose grid sweeps ``feeder.arrival``, or a study that replays
    one trace throughout): that point's replications are one sample, with no interval."""
    if one_trace(meta):
        return True
    scenario = (meta or {}).get("scenario") or {}
    grid = (meta or {}).get("grid") or {}
    if "feeder.trace" in grid or "feeder.arrival" not in values:
        return False
    robots = scenario.get("robots") or {}
    mtbf = values.get("robots.mtbf", robots.get("mtbf"))
    return values["feeder.arrival"] == "trace" and not mtbf and _trace_count(meta) == 1


def _with_ci(
    mean: float, low: Any, high: Any, trace: bool = False, confidence: float = 0.95
) -> str:
    if trace:
        return f"{fmt_pct(mean)} ({NO_INTERVAL})"
    ci = fmt_ci(low, high, confidence=confidence)
    return fmt_pct(mean) + (f" ({ci})" if ci else "")


def sweep_headline(study: Study) -> str:
    """The sweep's answer in one sentence: the best policy at the base line (with its paired
    margin over the runner-up there), the policy that wins most grid points, and the hardest
    point (the lowest best gripping rate)."""
    best, s, grid = study.best, study.summary, list(study.grid)
    if best is None or best.empty:
        return "The study has no results."
    trace = one_trace(study.meta)
    wins = best["policy"].value_counts()
    leader = str(wins.index[0])

    def g_at(point: dict[str, Any], policy: str) -> str:
        rows = at_point(s, point)
        row = rows[rows["policy"] == policy]
        if row.empty:
            return "–"
        r = row.iloc[0]
        return _with_ci(
            r["gripping_rate_mean"],
            r.get("gripping_rate_ci_low"),
            r.get("gripping_rate_ci_high"),
            trace or one_trace_at(study.meta, point),
        )

    if not grid:
        top = str(best.iloc[0]["policy"])
        return f"{top} is the best policy: {g_at({}, top)}" + _lead_margin(study, {}, top) + "."
    ref = reference_point(study)
    here = at_point(best, ref)
    top = str(here.iloc[0]["policy"]) if len(here) else leader
    scenario = study.meta.get("scenario") or {}
    own = all(scenario_value(scenario, p) == v for p, v in ref.items())
    where = "the base line" if own else "the middle of the grid"
    hard = best.loc[best["gripping_rate_mean"].idxmin()]
    hard_point = {p: hard[p] for p in grid}
    out = f"{top} is the best policy at {where} ({point_text(ref, grid)}): it grips "
    out += g_at(ref, top) + _lead_margin(study, ref, top)
    if len(best) > 1:
        share = f"{int(wins.iloc[0])} of {len(best)} grid points"
        if leader == top:
            out += f"; it is best at {share}"
        else:
            out += f"; {leader} is best at the most grid points ({share})"
    if hard_point != ref:
        out += f"; at the hardest point ({point_text(hard_point, grid)}) {top} grips "
        out += g_at(hard_point, top)
        if str(hard["policy"]) != top:
            out += f", where {hard['policy']} is best with {fmt_pct(hard['gripping_rate_mean'])}"
    return out + "."


def paired_margin(study: Study, point: dict[str, Any], policy: str) -> list[dict[str, Any]]:
    """``policy`` minus each other policy at ``point``, paired by replication (common random
    numbers): [{policy, diff_mean, diff_ci_low, diff_ci_high}], from the results table when
    the study has one, else from ``paired.csv`` when its reference there is ``policy``."""
    results = study.results
    out = []
    if results is not None and {"replication", "gripping_rate"} <= set(results.columns):
        rows = at_point(results, point)
        mine = rows[rows["policy"] == policy].set_index("replication")["gripping_rate"]
        for other in study.policies:
            if other == policy:
                continue
            theirs = rows[rows["policy"] == other].set_index("replication")["gripping_rate"]
            diff = (mine - theirs).dropna()
            if diff.empty:
                continue
            mean, low, high = t_interval(diff.to_numpy(), _confidence(study))
            out.append(
                {"policy": other, "diff_mean": mean, "diff_ci_low": low, "diff_ci_high": high}
            )
        return out
    paired = study.paired
    if paired is None or paired.empty:
        return []
    rows = at_point(paired, point)
    rows = rows[(rows["reference"] == policy) & (rows["policy"] != policy)]
    for _, r in rows.iterrows():  # paired.csv holds other minus the reference: turn it round
        out.append(
            {
                "policy": str(r["policy"]),
                "diff_mean": -float(r["diff_mean"]),
                "diff_ci_low": -float(r["diff_ci_high"]),
                "diff_ci_high": -float(r["diff_ci_low"]),
            }
        )
    return out


def _confidence(study: Study) -> float:
    try:
        return float(study.meta.get("confidence") or 0.95)
    except (TypeError, ValueError):
        return 0.95


def _lead_margin(study: Study, point: dict[str, Any], leader: str) -> str:
    """', 1.2 points (paired 95 % CI 0.8 to 1.6) ahead of SD' at one point: ``leader``
    against the runner-up there, paired by replication."""
    diffs = paired_margin(study, point, leader)
    if not diffs:
        return ""
    r = min(diffs, key=lambda d: d["diff_mean"])
    gap, lo, hi = float(r["diff_mean"]), float(r["diff_ci_low"]), float(r["diff_ci_high"])
    if one_trace(study.meta):
        return f", {gap:.2f} points ahead of {r['policy']} on that trace"
    ci = fmt_ci(lo, hi, 2, "")
    if math.isfinite(lo) and lo <= 0:
        return f", but it cannot be told apart from {r['policy']} ({gap:+.2f} points, paired {ci})"
    return f", {gap:.2f} points ahead of {r['policy']}" + (f" (paired {ci})" if ci else "")


def size_headline(sizing: dict[str, Any], trace: bool = False) -> str:
    """'N robots running RULE (G with its CI); rule of thumb M' in one sentence."""
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
            g = _with_ci(top["mean"], top["ci_low"], top["ci_high"], trace, conf)
            best = f" (best: {fmt_value(top['value'])} robots, {g})"
        return (
            f"No robot count tried reaches G ≥ {target:g} % with {conf * 100:g} % confidence"
            f"{best}{rot}."
        )
    row = next((r for r in rows if r["value"] == answer), None)
    g = f": G = {_with_ci(row['mean'], row['ci_low'], row['ci_high'], trace, conf)}" if row else ""
    rule = sizing.get("rule") or (row or {}).get("policy")
    running = f" running {rule}" if rule else ""
    return (
        f"{fmt_value(answer)} robots{running} reach G ≥ {target:g} % with {conf * 100:g} % "
        f"confidence{g}{rot}."
    )


def mix_headline(mix: dict[str, Any], trace: bool = False) -> str:
    """The best mix and its paired margin over the runner-up, or that they are a tie."""
    ranked = mix.get("ranked") or []
    if not ranked:
        return "The rule-mix search ranked no mix."
    top = ranked[0]
    g = _with_ci(float(top["gripping_rate_mean"]), top.get("ci_low"), top.get("ci_high"), trace)
    out = f"Best rule mix: {top['mix']} (robot 1 first), G = {g}"
    m = mix.get("margin")
    if not m or len(ranked) < 2:
        return out + "."
    ci = fmt_ci(m.get("ci_low"), m.get("ci_high"), 2, "")
    gap = float(m["diff_mean"])
    if m.get("distinguishable"):
        return out + f"; {gap:.2f} points ahead of {m['runner_up']} (paired {ci})."
    why = NO_INTERVAL if trace else (f"paired {ci}" if ci else "one replication gives no interval")
    return (
        out + f"; it cannot be told apart from {m['runner_up']} ({gap:+.2f} points, {why}): "
        "either mix will do, or run more replications to separate them."
    )


def headline(study: Study) -> str:
    """The report's answer in one sentence, by study kind."""
    trace = one_trace(study.meta)
    if study.sizing is not None:
        return size_headline(study.sizing, trace)
    if study.mix is not None:
        return mix_headline(study.mix, trace)
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
