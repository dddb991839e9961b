"""The design's answer in words: the choice, how sure, what it costs (with the interval the
lost-parts estimate gives it), the next best and, with a baseline, the payback."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

from pnp_twin.reports.text import fmt_bound, param_value
from pnp_twin.studies.kpi_choice import GRIPPING, KpiChoice
from pnp_twin.twin.scenario import Scenario

OVERRIDDEN = ("arm_speed", "pick_time", "place_time", "acceleration", "reach", "side", "kinds")


def line_notes(sc: Scenario, owned: Sequence[int] = ()) -> list[str]:
    """What the choice's robots differ in, for the buyer: each override ('robot 4 arm speed
    1.5 m/s') and the robots already owned."""
    notes = []
    for o in sorted(sc.robots.overrides, key=lambda o: o.robot):
        if o.robot > sc.robots.count:
            continue
        for name in OVERRIDDEN:
            value = getattr(o, name)
            if value is not None:
                notes.append(f"robot {o.robot} {param_value(f'robots.{name}', value, True)}")
    mine = [i for i in owned if i <= sc.robots.count]
    if mine:
        which = ", ".join(map(str, mine))
        notes.append(f"robot{'s' if len(mine) > 1 else ''} {which} already owned")
    return notes


def choice_text(choice: Mapping[str, Any], notes: Sequence[str] = ()) -> str:
    """'6 robots, arm speed 4 m/s (robot 4 arm speed 1.5 m/s) running SPT' from a choice
    mapping and the line's notes."""
    words = []
    for path, value in choice.items():
        if path == "policy":
            continue
        if path == "robots.count":
            words.append(f"{value} robots")
        elif isinstance(value, int | float) and not isinstance(value, bool):
            words.append(param_value(path, value, lower=True))
        else:
            words.append(f"{path.rsplit('.', 1)[-1]} {value}")
    extra = f" ({'; '.join(notes)})" if notes else ""
    return ", ".join(words) + extra + f" running {choice.get('policy')}"


def _money(x: float) -> str:
    return f"{x:,.0f}" if math.isfinite(x) else "–"


def cost_text(d: Mapping[str, Any]) -> str:
    """'total cost 160,000 [158,000, 162,000] (capital 150,000; running 10,000: lost parts
    over 4,000 h; 0.0123 per part gripped)'; just the total without a cost file."""
    if not d.get("cost_file"):
        return f"total cost {_money(d['total_cost'])}"
    hours = float(d["costs"]["hours"])
    per_part = d.get("cost_per_part")
    each = f"; {per_part:.4g} per part gripped" if per_part is not None else ""
    return (
        f"total cost {_money(d['total_cost'])} [{_money(d['total_cost_low'])}, "
        f"{_money(d['total_cost_high'])}] (capital {_money(d['capital_cost'])}; running "
        f"{_money(d['running_cost'])}: lost parts over {hours:,.0f} h{each})"
    )


def alternative_text(d: Mapping[str, Any]) -> str:
    """The next best other hardware: how much more it costs, or that the two cannot be told
    apart (the difference's interval holds 0: lost parts are estimated from a few runs)."""
    mine = {k: v for k, v in d["choice"].items() if k != "policy"}
    other = [
        a
        for a in d["alternatives"]
        if {k: v for k, v in a["choice"].items() if k != "policy"} != mine
    ]
    if not other:
        return ""
    a = other[0]
    name = choice_text(a["choice"])
    extra = a["total_cost"] - d["total_cost"]
    low, high = a.get("extra_low", extra), a.get("extra_high", extra)
    capital = a["capital_cost"] - d["capital_cost"]
    if low <= 0 <= high and (low, high) != (0, 0):
        buy = (
            "the same to buy"
            if capital == 0
            else f"{_money(abs(capital))} {'cheaper' if capital < 0 else 'dearer'} to buy"
        )
        return (
            f"; {name} also meets it and costs the same within the lost parts' noise "
            f"({extra:+,.0f}, interval {low:+,.0f} to {high:+,.0f}, from {a['replications']} "
            f"and {d['replications']} runs; {buy})"
        )
    if capital == 0:
        return f"; {name} also meets it on the same hardware for {_money(extra)} more in lost parts"
    span = f" [{_money(low)}, {_money(high)}]" if low != high else ""
    return f"; {name} also meets it for {_money(extra)} more{span}"


def payback_text(p: Mapping[str, Any] | None) -> str:
    """'Against today's line (G 85.0 % [83.0, 87.0]) it saves 12,300 a year [10,100,
    14,500] in lost parts and pays its capital back in 14.6 months [12.4, 17.8].'"""
    if not p:
        return ""
    today = (
        f" Against today's line (G {p['gripping_rate']:.1f} % "
        f"[{p['ci_low']:.1f}, {p['ci_high']:.1f}], {p['replications']} runs)"
    )
    year = (
        f"{_money(p['saving_per_year'])} a year [{_money(p['saving_low'])}, "
        f"{_money(p['saving_high'])}] in lost parts over {p['hours_per_year']:,.0f} h a year"
    )
    if p["saving_per_year"] <= 0:
        return f"{today} it saves nothing ({year}): its capital is not paid back by lost parts."
    months = p["payback_months"]
    slow = p["payback_months_high"]
    late = f"{slow:.1f}" if slow is not None else "never (the saving's interval reaches 0)"
    return (
        f"{today} it saves {year} and pays its capital of {_money(p['capital'])} back in "
        f"{months:.1f} months [{p['payback_months_low']:.1f}, {late}]."
    )


def design_text(d: dict[str, Any], kpi: KpiChoice = GRIPPING) -> str:
    """The answer in one sentence (on the ``kpi`` figure), with the next best for how much
    more, and the payback against today's line where one was given."""
    conf = f"{100 * d['confidence']:g} %"
    k, n = d["configurations"], d.get("evaluated", d["configurations"])
    among = f"{k} configurations" if n == k else f"the {n} points evaluated (of {k} allowed)"
    conditions = d.get("conditions") or []
    at = f" at each of {len(conditions)} conditions" if len(conditions) > 1 else ""
    if d["choice"] is None:
        return (
            f"No configuration of the {n} tried meets {kpi.short} ≥ {d['target']:g} %{at} "
            f"with {conf} confidence (after selecting among them)."
        )
    worst = " (the worst condition's)" if at else ""
    out = (
        f"{choice_text(d['choice'], d.get('notes') or ())}: {kpi.short} = "
        f"{d['gripping_rate']:.1f} % [{fmt_bound(d['ci_low'], d['target'])}, "
        f"{fmt_bound(d['ci_high'], d['target'])}]{worst} meets "
        f"{kpi.short} ≥ {d['target']:g} %{at} with {conf} confidence after selecting among "
        f"{among}; {cost_text(d)}"
    )
    shifts = ""
    if "feeder.trace" in (d.get("across") or {}):
        shifts = (
            f" Each of the {len(d['across']['feeder.trace'])} traces is replayed as recorded: "
            "its interval covers only the runs' own randomness (none for a rule that draws no "
            "random numbers), so the answer is about these shifts, not shifts unlike them."
        )
    return out + alternative_text(d) + "." + shifts + payback_text(d.get("payback"))
