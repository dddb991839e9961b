"""Words and numbers for humans: parameter labels, number formats, the sizing answer and the
key findings of a study, in plain sentences a plant engineer can forward."""

from __future__ import annotations

import math
import typing
from typing import Any

import numpy as np
import pandas as pd

from pnp_twin.reports.load import Study
from pnp_twin.twin.scenario import Scenario

# dotted scenario path -> (label, short label, unit)
PARAMS: dict[str, tuple[str, str, str]] = {
    "robots.arm_speed": ("Arm speed", "arm", "m/s"),
    "feeder.rate": ("Part flow", "flow", "parts/s"),
    "belt.speed": ("Belt speed", "belt", "m/s"),
    "robots.count": ("Robots", "robots", ""),
    "robots.pick_time": ("Pick time", "pick", "s"),
    "robots.place_time": ("Place time", "place", "s"),
    "robots.acceleration": ("Arm acceleration", "accel", "m/s²"),
    "robots.workspace_length": ("Workspace length", "workspace", "m"),
    "robots.mtbf": ("Mean time between failures", "MTBF", "s"),
    "robots.mttr": ("Mean time to repair", "MTTR", "s"),
    "belt.width": ("Belt width", "width", "m"),
    "belt.length": ("Belt length", "length", "m"),
    "feeder.cv": ("Gap variation (CV)", "CV", ""),
    "termination": ("Termination", "term.", ""),
    "bins.capacity": ("Box capacity", "box", "parts"),
    "bins.change_time": ("Box change time", "change", "s"),
}


def _fallback(path: str) -> tuple[str, str, str]:
    """A path PARAMS does not list: its section and field ('belt.length' -> 'Belt length';
    a robots field without 'robots') and the unit the scenario schema gives it."""
    *section, name = path.split(".")
    words = [w for w in section if w != "robots"] + [name]
    label = " ".join(words).replace("_", " ").capitalize()
    return label, name, schema_unit(path)


def schema_unit(path: str) -> str:
    """The unit of a scenario field as the schema states it ('' if none or not a field)."""
    model: Any = Scenario
    field = None
    for key in path.split("."):
        fields = getattr(model, "model_fields", {})
        if key not in fields:
            return ""
        field = fields[key]
        ann = field.annotation
        options = typing.get_args(ann) or (ann,)
        model = next(
            (a for a in options if isinstance(a, type) and hasattr(a, "model_fields")), None
        )
    extra = getattr(field, "json_schema_extra", None)
    unit = extra.get("unit", "") if isinstance(extra, dict) else ""
    return str(unit) if unit not in ("", "1") else ""


def param_label(path: str, unit: bool = True) -> str:
    """'robots.arm_speed' -> 'Arm speed (m/s)'; unknown paths get their section, field and
    the schema's unit ('belt.length' -> 'Belt length (m)')."""
    label, _, u = PARAMS.get(path) or _fallback(path)
    return f"{label} ({u})" if unit and u else label


def fmt_value(value: Any) -> str:
    """A grid value as short text: 0.8, 12, t_all."""
    if isinstance(value, bool | str):
        return str(value)
    if isinstance(value, int | float | np.integer | np.floating):
        return f"{float(value):g}"
    return str(value)


def fmt_bound(x: float, target: float, digits: int = 1) -> str:
    """A bound of an interval with as many decimals as it takes not to round across the
    target: 94.99 against 95 is '94.99', not '95.0' (which would read as meeting it)."""
    d = digits
    while d < 4 and (round(x, d) >= target) != (x >= target):
        d += 1
    return f"{x:.{d}f}"


def param_value(path: str, value: Any, lower: bool = False) -> str:
    """'Arm speed 4 m/s' ('arm speed 4 m/s' inside a sentence); an MTBF of 0 is 'no
    breakdowns'."""
    if path == "robots.mtbf" and not value:
        return "no breakdowns" if lower else "No breakdowns"
    label, _, unit = PARAMS.get(path) or _fallback(path)
    label = label.lower() if lower and not label.isupper() else label
    return f"{label} {fmt_value(value)}{' ' + unit if unit else ''}"


NEVER = "robots.mtbf"  # 0 means no breakdowns: an MTBF of infinity, not of zero


def order_key(path: str, value: Any) -> Any:
    """Sort key of a grid value along its axis: an MTBF of 0 (no breakdowns) is infinitely
    reliable, so it sorts after every real MTBF."""
    if path == NEVER and not value:
        return math.inf
    return value


def sorted_values(path: str, values: Any) -> list[Any]:
    """``values`` in axis order (:func:`order_key`)."""
    return sorted(list(values), key=lambda v: order_key(path, v))


def sort_rows(frame: pd.DataFrame, path: str) -> pd.DataFrame:
    """``frame`` sorted along the ``path`` axis (:func:`order_key`)."""
    keys = [order_key(path, v) for v in frame[path]]
    return frame.iloc[sorted(range(len(frame)), key=keys.__getitem__)]


def axis_text(path: str, value: Any) -> str:
    """A grid value as an axis tick: '600', or 'none (∞)' for an MTBF of 0."""
    if path == NEVER and not value:
        return "none (∞)"
    return fmt_value(value)


def is_category_axis(path: str, values: Any) -> bool:
    """True when the axis cannot be numeric: an MTBF axis that holds 'no breakdowns'."""
    return path == NEVER and any(not v for v in values)


def value_text(path: str, value: Any) -> str:
    """'600 s'; 'no breakdowns' for an MTBF of 0."""
    if path == NEVER and not value:
        return "no breakdowns"
    unit = PARAMS.get(path, ("", "", ""))[2]
    return f"{fmt_value(value)}{' ' + unit if unit else ''}"


def point_label(row: pd.Series | dict[str, Any], grid: list[str]) -> str:
    """A grid point in a few words: 'belt 0.8 · arm 4 · flow 12'."""
    parts = []
    for path in grid:
        short = PARAMS.get(path, ("", path.rsplit(".", 1)[-1], ""))[1]
        if path == "robots.mtbf" and not row[path]:
            parts.append("no breakdowns")
            continue
        parts.append(f"{short} {fmt_value(row[path])}")
    return " · ".join(parts) if parts else "baseline"


def point_text(row: pd.Series | dict[str, Any], grid: list[str]) -> str:
    """A grid point in a sentence: 'arm speed 4 m/s, part flow 12 parts/s'."""
    return ", ".join(param_value(p, row[p], lower=True) for p in grid)


def fmt_pct(value: float, digits: int = 1) -> str:
    """72.345 -> '72.3 %'; NaN -> '–'."""
    return "–" if value is None or not math.isfinite(value) else f"{value:.{digits}f} %"


def fmt_pm(low: float, high: float, digits: int = 1) -> str:
    """A confidence interval as its half width: '± 1.2'; empty when unknown."""
    if low is None or high is None or not (math.isfinite(low) and math.isfinite(high)):
        return ""
    return f"± {(high - low) / 2:.{digits}f}"


def fmt_seconds(seconds: float) -> str:
    """12.3 -> '12.3 s'; 754 -> '12 min 34 s'."""
    if seconds is None or not math.isfinite(seconds):
        return "–"
    if seconds < 60:
        return f"{seconds:.1f} s"
    minutes, sec = divmod(round(seconds), 60)
    if minutes < 60:
        return f"{minutes} min {sec} s"
    return f"{minutes // 60} h {minutes % 60} min"


def scenario_value(scenario: dict[str, Any], path: str) -> Any:
    """The value at dotted ``path`` in a scenario dict, or None."""
    node: Any = scenario
    for key in path.split("."):
        if not isinstance(node, dict) or key not in node:
            return None
        node = node[key]
    return node


def reference_point(study: Study) -> dict[str, Any]:
    """Where to hold each grid parameter when another one varies: the scenario's own value
    when the grid holds it, else the middle value of the grid."""
    scenario = study.meta.get("scenario") or {}
    ref = {}
    for path, values in study.grid.items():
        own = scenario_value(scenario, path)
        ref[path] = own if own in values else values[(len(values) - 1) // 2]
    return ref


def at_point(table: pd.DataFrame, point: dict[str, Any]) -> pd.DataFrame:
    """Rows of ``table`` whose grid columns equal ``point``."""
    mask = np.ones(len(table), dtype=bool)
    for path, value in point.items():
        mask &= (table[path] == value).to_numpy()
    return table[mask]


def _get(row: dict[str, Any], *keys: str) -> Any:
    for key in keys:
        if key in row and row[key] is not None:
            return row[key]
    return None


SIZING_KEYS = {"value", "count", "point", "policy", "reached", "mean", "gripping_rate_mean"}
SIZING_KEYS |= {"ci_low", "ci_high", "gripping_rate_ci_low", "gripping_rate_ci_high"}
SIZING_KEYS |= {"rules", "confidence_each"}  # how the rule was picked, not a condition


def sizing_rows(sizing: dict[str, Any]) -> list[dict[str, Any]]:
    """The sizing table as uniform rows: value, mean, ci_low, ci_high, reached, policy, and
    ``condition``, the text of the other swept parameters (e.g. 'robots.mtbf 600')."""
    param = str(sizing.get("parameter") or "robots.count")
    rows = []
    for r in sizing.get("rows") or []:
        others = {k: v for k, v in r.items() if k != param and k not in SIZING_KEYS}
        rows.append(
            {
                "value": _get(r, "value", param, "count"),
                "mean": _get(r, "gripping_rate_mean", "mean"),
                "ci_low": _get(r, "ci_low", "gripping_rate_ci_low"),
                "ci_high": _get(r, "ci_high", "gripping_rate_ci_high"),
                "reached": bool(r.get("reached")),
                "policy": r.get("policy"),
                "condition": condition_text(others),
            }
        )
    return rows


def condition_text(values: dict[str, Any]) -> str:
    """Other swept parameters of a sizing row in words; breakdowns off reads 'no breakdowns'."""
    words = []
    for path, value in values.items():
        if path == "robots.mtbf":
            words.append("no breakdowns" if not value else f"breakdowns, MTBF {fmt_value(value)} s")
        else:
            words.append(param_value(path, value, lower=True))
    return ", ".join(words)


def sizing_text(sizing: dict[str, Any], trace: bool = False) -> list[str]:
    """The sizing answer in plain sentences, the answer first."""
    param = str(sizing.get("parameter") or "robots.count")
    target = float(sizing.get("target") or math.nan)
    conf = float(sizing.get("confidence") or 0.95)
    answer = sizing.get("answer")
    rows = sizing_rows(sizing)
    what = "robots" if param == "robots.count" else param_label(param, unit=False).lower()
    goal = f"a gripping rate of {fmt_pct(target)} with {conf * 100:g} % confidence"
    out = []
    if answer is None:
        tried = [fmt_value(r["value"]) for r in rows if r["value"] is not None]
        span = f" ({tried[0]} to {tried[-1]})" if tried else ""
        out.append(f"None of the values tried{span} reaches {goal}.")
        if rows:
            top = max(rows, key=lambda r: r["mean"] if r["mean"] is not None else -1)
            out.append(
                f"The best, {fmt_value(top['value'])} {what}, averages {fmt_pct(top['mean'])}; "
                "widen the range or change the line."
            )
    else:
        if param == "robots.count":
            head = f"The line needs {fmt_value(answer)} robots to reach {goal}"
        else:
            head = f"{param_value(param, answer)} is what reaches {goal}"
        row = next(
            (r for r in rows if r["value"] == answer and r["condition"] in ("", "no breakdowns")),
            None,
        )
        rule = sizing.get("rule") or (row or {}).get("policy")
        if rule and param == "robots.count":
            head += f", running {rule}"
        if row is not None and row["mean"] is not None and trace:
            head += f" (mean {fmt_pct(row['mean'])}; one replayed trace: no interval)"
        elif row is not None and row["mean"] is not None:
            lo, hi = row["ci_low"], row["ci_high"]
            # a t-interval of few replications can pass 100 %, which no line can
            ci = (
                f", {conf * 100:g} % CI {lo:.1f} to {min(hi, 100.0):.1f} %"
                if lo is not None and hi
                else ""
            )
            head += f" (mean {fmt_pct(row['mean'])}{ci})"
        out.append(head + ".")
    chosen = (sizing.get("selection") or {}).get("text")
    if chosen:
        out.append(str(chosen))
    thumb = sizing.get("rule_of_thumb") or {}
    n_min, flow, ppas = thumb.get("n_min"), thumb.get("part_flow"), thumb.get("ppas")
    if n_min is not None and flow is not None and ppas is not None:
        s = (
            f"The rule of thumb N_min = f_p / PPas = {float(flow):.1f} / {float(ppas):.2f} "
            f"= {float(n_min):.1f} robots"
        )
        if thumb.get("n_recommended") is not None:
            s += f", {fmt_value(thumb['n_recommended'])} with the safety margin"
        out.append(s + ".")
    down = sizing.get("breakdown") or {}
    if down:
        avail = down.get("availability")
        words = []
        if down.get("mtbf") is not None and down.get("mttr") is not None:
            words.append(
                f"MTBF {fmt_value(down['mtbf'])} s, MTTR {fmt_value(down['mttr'])} s"
                + (" (assumed: the scenario sets no breakdowns)" if down.get("assumed") else "")
            )
        if avail is not None:
            words.append(f"availability {100 * float(avail):.1f} %")
        s = "Allowing for breakdowns" + (f" ({'; '.join(words)})" if words else "")
        n = down.get("n_with_failures")
        if n is not None:
            out.append(f"{s}, plan for {fmt_value(n)} robot{'' if n == 1 else 's'}.")
        elif words:
            out.append(f"{s}, no robot count tried reaches the target.")
    minus = down.get("n_minus_1")
    if isinstance(minus, dict) and minus.get("gripping_rate_mean") is not None:
        working = minus.get("robots", minus.get("robots.count", "N − 1"))
        out.append(
            f"With one robot down ({fmt_value(working)} working) the gripping rate drops to "
            f"{fmt_pct(float(minus['gripping_rate_mean']))}."
        )
    return out


def mix_findings(study: Study) -> list[str]:
    """A rule-mix search in a few sentences, never a list of every mix: the best and the
    runner-up (the best minus the runner-up, so a positive gap means the best is ahead),
    how many mixes cannot be told from the best, the best uniform rule and the worst mix."""
    mix = study.mix or {}
    ranked = mix.get("ranked") or []
    if not ranked:
        return ["The rule-mix search ranked no mix."]
    top = ranked[0]
    best_g = float(top["gripping_rate_mean"])
    out = [f"{len(ranked)} mixes evaluated; the best, {top['mix']}, grips {fmt_pct(best_g)}."]
    m = mix.get("margin")
    if m and len(ranked) > 1:
        gap = float(m["diff_mean"])
        lo, hi = m.get("ci_low"), m.get("ci_high")
        ci = (
            f" (paired 95 % CI {float(lo):.2f} to {float(hi):.2f})"
            if lo is not None and hi is not None and math.isfinite(float(lo))
            else ""
        )
        out.append(f"The runner-up, {m['runner_up']}, is {gap:.2f} points behind the best{ci}.")
    paired = study.paired
    if paired is not None and not paired.empty and len(ranked) > 2:
        others = paired[paired["policy"] != paired["reference"]]
        tied = others[others["diff_ci_high"] >= 0]
        if len(tied):
            out.append(
                f"{len(tied)} of the other {len(others)} mixes cannot be told apart from the "
                "best (their paired 95 % CI of the difference reaches zero)."
            )
    uniform = [r for r in ranked if len(set(str(r["mix"]).split(","))) == 1]
    if uniform and uniform[0] is not top:
        u = uniform[0]
        rule = str(u["mix"]).split(",")[0]
        below = best_g - float(u["gripping_rate_mean"])
        out.append(
            f"The best single rule on every robot, {rule}, grips "
            f"{fmt_pct(float(u['gripping_rate_mean']))}: {below:.2f} points below the best mix."
        )
    if len(ranked) > 2:
        worst = ranked[-1]
        below = best_g - float(worst["gripping_rate_mean"])
        out.append(
            f"The worst mix, {worst['mix']}, grips {fmt_pct(float(worst['gripping_rate_mean']))}"
            f": {below:.2f} points below the best."
        )
    return out


def key_findings(study: Study) -> list[str]:
    """Three to six plain sentences: best and worst point, policy wins, parameter effects."""
    if study.mix is not None:
        return mix_findings(study)
    s = study.summary
    grid = list(study.grid)
    out = []
    hi = s.loc[s["gripping_rate_mean"].idxmax()]
    lo = s.loc[s["gripping_rate_mean"].idxmin()]
    where = lambda row: f" at {point_text(row, grid)}" if grid else ""  # noqa: E731
    out.append(
        f"Highest mean gripping rate: {fmt_pct(hi['gripping_rate_mean'])} with "
        f"{hi['policy']}{where(hi)}; lowest: {fmt_pct(lo['gripping_rate_mean'])} with "
        f"{lo['policy']}{where(lo)}."
    )
    policies = study.policies
    best = study.best
    if len(policies) > 1 and best is not None and len(best):
        wins = best["policy"].value_counts()
        leader = str(wins.index[0])
        out.append(
            f"{leader} is the best policy at {int(wins.iloc[0])} of {len(best)} grid point"
            f"{'s' if len(best) != 1 else ''}."
        )
        gap = policy_gaps(study)
        if len(gap):
            parts = [f"{p} {g:.1f}" for p, g in gap.items() if g > 0]
            if parts:
                out.append(
                    "Average gap to the best policy, in gripping-rate points: "
                    + ", ".join(parts)
                    + "."
                )
    ref = reference_point(study)
    bursts = burst_cost(study)
    if bursts:
        out.append(bursts)
    for path in study.varying:
        if path == "feeder.arrival":
            continue  # said by burst_cost, in words
        fixed = {k: v for k, v in ref.items() if k != path}
        rows = at_point(study.best if best is not None else s, fixed)
        rows = sort_rows(rows, path)
        if len(rows) >= 2:
            a, b = rows.iloc[0], rows.iloc[-1]
            out.append(
                f"{param_label(path, unit=False)} from {value_text(path, a[path])} to "
                f"{value_text(path, b[path])}: best gripping "
                f"rate {fmt_pct(a['gripping_rate_mean'])} → {fmt_pct(b['gripping_rate_mean'])}"
                + (f" ({point_text(fixed, list(fixed))})." if fixed else ".")
            )
    return out


def burst_cost(study: Study) -> str:
    """With ``feeder.arrival`` swept over a trace and random arrivals at the trace's mean
    rate: what the trace's burstiness costs, in points of the best G ('' otherwise)."""
    values = study.grid.get("feeder.arrival") or []
    if "trace" not in values or len(values) < 2 or study.best is None:
        return ""
    ref = {k: v for k, v in reference_point(study).items() if k != "feeder.arrival"}
    rows = at_point(study.best, ref)
    g = {str(r["feeder.arrival"]): float(r["gripping_rate_mean"]) for _, r in rows.iterrows()}
    if "trace" not in g:
        return ""
    names = {"poisson": "Poisson arrivals", "normal": "normal gaps with the trace's CV"}
    names["fixed"] = "evenly spaced parts"
    others = [a for a in ("poisson", "normal", "fixed") if a in g]
    if not others:
        return ""
    first = others[0]
    words = ", ".join(f"{names[a]} {fmt_pct(g[a])}" for a in others)
    where = f" ({point_text(ref, list(ref))})" if ref else ""
    return (
        f"Bursts cost {g[first] - g['trace']:.1f} points: the replayed trace grips "
        f"{fmt_pct(g['trace'])}, at the same mean rate {words}{where}."
    )


def policy_gaps(study: Study) -> pd.Series:
    """Mean paired difference to the best policy per policy, in points (positive = worse)."""
    if study.paired is None or study.paired.empty:
        return pd.Series(dtype=float)
    gaps = -study.paired.groupby("policy")["diff_mean"].mean()
    return gaps.reindex([p for p in study.policies if p in gaps.index])
