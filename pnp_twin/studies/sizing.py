"""Sizing answers: the smallest robot count (slowest arm, highest flow) reaching a target.

A count *reaches* the target gripping rate G* with confidence c when the lower bound of the
two-sided c t-interval of its mean G over replications is at least G* (the best policy at
that grid point). The answer is chosen so that the confidence holds after choosing it: the
counts are tested in a fixed sequence, from the largest down, each at the full level, and
the sequence stops at the first count that misses the target (in any swept condition); the
answer is the smallest count of that unbroken run. With several rules each rule is its own
sequence, every interval at the Bonferroni level over the rules, and the answer is the
smallest count any rule's sequence reaches (:func:`fixed_sequence`). A count that reaches the
target below a count that misses it is not the answer: that would be testing every count at
the full level and keeping the smallest pass, whose error grows with the counts tried.

The answer sits next to the empirical rule of MODEL.md, N_min = f_p / PPas, where PPas is
the picks per second of one saturated robot, measured in the study as throughput /
(N x utilisation) at its smallest robot count, plus a safety margin of 20 % (rounded up):
``n_recommended = ceil(1.2 x N_min)``.

Breakdowns: ``size`` adds ``robots.mtbf`` to the grid, [0, MTBF], with the scenario's MTBF
and MTTR or, when it has none, the assumption of a gripper jam every 10 minutes cleared in
30 s (MTBF 600 s, MTTR 30 s, availability A = MTBF / (MTBF + MTTR) = 95.2 %). The answer is
taken without failures; ``breakdown`` gives the count needed with them, and what one robot
down does to the answer (the gripping rate of N - 1 robots: a stopped robot's workspace is
just belt the parts pass through).

Layout (``--layout``): more robots need belt. ``extend`` (the default) keeps each workspace's
length and lengthens the belt to fit the largest count; ``share`` keeps the belt and the
stretch the scenario's robots cover, and divides it among N narrower workspaces (length
(span - (N - 1) gap) / N). ``sizing.json`` states the choice and each count's layout.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Mapping, Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any

import pandas as pd

from pnp_twin.studies.folder import Tables, write_records
from pnp_twin.studies.kpi_choice import GRIPPING, KpiChoice
from pnp_twin.studies.plan import RunSpec, StudyError, StudyPlan, build_plan
from pnp_twin.studies.runner import Options, finish, open_session, run_plan
from pnp_twin.twin.loader import ScenarioError, with_overrides
from pnp_twin.twin.output import write_json
from pnp_twin.twin.scenario import Scenario
from pnp_twin.twin.stats import t_interval

COUNT = "robots.count"
MTBF = "robots.mtbf"
DEFAULT_MTBF = 600.0  # s: a gripper jam every 10 minutes
DEFAULT_MTTR = 30.0  # s: cleared in half a minute
MARGIN = 0.20  # the rule of thumb's safety margin
LIMITS = {"robots.arm_speed": "slowest", "feeder.rate": "highest"}
LAYOUTS = ("extend", "share")


def sizing_setup(
    scenario: Scenario, grid: Mapping[str, Sequence[Any]], layout: str = "extend"
) -> tuple[Scenario, dict[str, list[Any]]]:
    """The scenario and grid a sizing study runs: robot counts, failures off and on; the belt
    lengthened for the largest count (``extend``) or its workspaces narrowed (``share``)."""
    if layout not in LAYOUTS:
        raise StudyError(f"--layout: '{layout}' is not allowed; allowed {', '.join(LAYOUTS)}")
    out: dict[str, list[Any]] = {k: list(v) for k, v in grid.items()}
    if COUNT not in out:
        n = scenario.robots.count
        out = {COUNT: list(range(1, max(8, 2 * n) + 1)), **out}
    if scenario.robots.workspaces is not None:
        raise StudyError(
            "robots.workspaces: an explicit layout cannot follow a swept robots.count; use "
            "robots.first_workspace_start and robots.workspace_length instead"
        )
    counts = out[COUNT]
    if not all(isinstance(c, int) and not isinstance(c, bool) and c >= 1 for c in counts):
        raise StudyError(f"sweep.grid.{COUNT}: {counts} must be whole numbers >= 1")
    r = scenario.robots
    mtbf = r.mtbf if r.mtbf > 0 else DEFAULT_MTBF
    mttr = r.mttr if r.mttr > 0 else DEFAULT_MTTR
    out.setdefault(MTBF, [0.0, mtbf])
    base: dict[str, Any] = {"robots.mttr": mttr}
    if layout == "extend":
        deepest = r.deepest(max(counts))  # per side: facing robots share x-ranges
        end = r.first_workspace_start + deepest * (r.workspace_length + r.workspace_gap)
        base["belt.length"] = max(scenario.belt.length, round(end + 0.1, 3))
    else:  # every point validates with the narrowest workspaces; share_layout sets each
        base["robots.workspace_length"] = shared_length(scenario, max(counts))
    try:
        return with_overrides(scenario, base), out
    except ScenarioError as e:
        raise StudyError(f"size: {e}") from None


def shared_length(scenario: Scenario, n: int) -> float:
    """Workspace length of ``n`` robots sharing the stretch the scenario's robots cover
    (laid out per side: the side with the most robots sets it)."""
    r = scenario.robots
    now, then = r.deepest(), r.deepest(n)
    span = now * r.workspace_length + (now - 1) * r.workspace_gap
    length = (span - (then - 1) * r.workspace_gap) / then
    if length <= 0:
        raise StudyError(
            f"--layout share: {n} robots with workspace_gap {r.workspace_gap:g} m do not fit "
            f"in the {span:g} m the scenario's robots cover; use --layout extend"
        )
    return length


def share_layout(plan: StudyPlan, scenario: Scenario) -> StudyPlan:
    """``plan`` with each point's workspaces narrowed to share the scenario's stretch."""
    out = []
    for point, sc in zip(plan.points, plan.scenarios, strict=True):
        length = shared_length(scenario, int(point[COUNT]))
        out.append(with_overrides(sc, {"robots.workspace_length": length}))
    return replace(plan, scenarios=tuple(out))


def layout_summary(plan: StudyPlan, layout: str) -> dict[str, Any]:
    """The layout choice and, per robot count, the belt and workspaces the study ran."""
    counts: dict[str, Any] = {}
    for point, sc in zip(plan.points, plan.scenarios, strict=True):
        n = int(point[COUNT])
        if str(n) not in counts:
            counts[str(n)] = {
                "belt_length": sc.belt.length,
                "workspace_length": sc.robots.workspace_length,
                "workspaces": [list(w) for w in sc.robots.layout()],
            }
    base = plan.scenario
    return {"mode": layout, "belt_length": base.belt.length, "counts": counts}


def layout_text(layout: dict[str, Any], scenario: Scenario) -> str:
    """One sentence on how the robots were laid out."""
    r = scenario.robots
    if layout["mode"] == "share":
        deep = r.deepest()
        span = deep * r.workspace_length + (deep - 1) * r.workspace_gap
        per = "N" if deep == r.count else "the robots on the fullest side"
        return (
            f"Layout: share. The {scenario.belt.length:g} m belt is kept; N robots share the "
            f"{span:g} m stretch that the scenario's {r.count} robots cover, each with a "
            f"workspace of {span:g} / {per} m."
        )
    longest = max(c["belt_length"] for c in layout["counts"].values())
    grown = (
        f"the belt is lengthened from {scenario.belt.length:g} m to {longest:g} m"
        if longest > scenario.belt.length
        else f"the {scenario.belt.length:g} m belt fits every count"
    )
    return (
        f"Layout: extend. Each robot keeps a {r.workspace_length:g} m workspace and {grown}; "
        "use --layout share to keep the belt instead."
    )


def _conditions(summary: pd.DataFrame, paths: Sequence[str]) -> list[dict[str, Any]]:
    if not paths:
        return [{}]
    values = [list(dict.fromkeys(summary[p])) for p in paths]
    return [dict(zip(paths, combo, strict=True)) for combo in itertools.product(*values)]


def _select(frame: pd.DataFrame, condition: Mapping[str, Any]) -> pd.DataFrame:
    mask = pd.Series(True, index=frame.index)
    for k, v in condition.items():
        mask &= frame[k] == v
    return frame[mask]


def selected_confidence(confidence: float, rules: int) -> float:
    """The confidence of each rule's interval so that all ``rules`` intervals hold together
    with ``confidence`` (Bonferroni): what keeps the promise after picking the best rule."""
    return 1.0 - (1.0 - confidence) / max(1, rules)


def point_rows(
    summary: pd.DataFrame,
    grid: Sequence[str],
    target: float,
    results: pd.DataFrame | None = None,
    confidence: float = 0.95,
    column: str = "gripping_rate",
) -> pd.DataFrame:
    """Per grid point, the rule to run there, its mean G and CI, and whether it reached the
    target. With several rules the best one is picked after seeing the data, so its own
    interval would be optimistic: each rule's interval is taken at the Bonferroni level
    :func:`selected_confidence` (computed from ``results``), the rule with the highest such
    lower bound is the one to run, and the point reaches the target when that bound does.
    ``column``: the results' figure the target is on (``--kpi``; its mean and interval go
    under ``gripping_rate_mean``, ``ci_low`` and ``ci_high``)."""
    best = summary.loc[summary.groupby("point")["gripping_rate_mean"].idxmax()]
    if results is None or results.empty:
        out = best[["point", *grid, "policy"]].copy()
        out["gripping_rate_mean"] = best["gripping_rate_mean"]
        out["ci_low"] = best["gripping_rate_ci_low"]
        out["ci_high"] = best["gripping_rate_ci_high"]
        out["reached"] = (best["gripping_rate_ci_low"] >= target).to_numpy()
        return out.reset_index(drop=True)
    each = rule_rows(results, grid, target, confidence, column)

    def key(i: Any) -> tuple[float, float]:  # ties: the first rule given
        low = float(each.at[i, "ci_low"])
        return (low if math.isfinite(low) else -math.inf, float(each.at[i, "gripping_rate_mean"]))

    picked = [max(at.index, key=key) for _, at in each.groupby("point", sort=True)]
    return each.loc[picked].reset_index(drop=True)


def rule_rows(
    results: pd.DataFrame,
    grid: Sequence[str],
    target: float,
    confidence: float,
    column: str = "gripping_rate",
) -> pd.DataFrame:
    """Per grid point and rule: mean G and its interval at the Bonferroni level over the
    point's rules (:func:`selected_confidence`), and whether the lower bound reaches the
    target."""
    rows = []
    for point, at in results.groupby("point", sort=True):
        rules = list(dict.fromkeys(at["policy"]))
        level = selected_confidence(confidence, len(rules))
        first = at.iloc[0]
        for rule in rules:
            mean, low, high = t_interval(at.loc[at["policy"] == rule, column], level)
            low, high = max(low, 0.0), min(high, 100.0)  # G cannot leave [0, 100]
            rows.append(
                {
                    "point": int(point),
                    **{c: first[c] for c in grid},
                    "policy": rule,
                    "gripping_rate_mean": mean,
                    "ci_low": low,
                    "ci_high": high,
                    "reached": bool(math.isfinite(low) and low >= target),
                    "rules": len(rules),
                    "confidence_each": level,
                }
            )
    return pd.DataFrame(rows)


def fixed_sequence(
    each: pd.DataFrame, conditions: list[dict[str, Any]]
) -> tuple[int | None, str | None]:
    """The smallest count, and its rule, that a fixed-sequence test per rule accepts: each
    rule's counts are tested from the largest down, each at the full (Bonferroni over rules)
    level, and the sequence stops at the first count where the rule misses the target in
    some condition; the answer is the smallest count of the unbroken run from the top,
    over the rules (ties: the higher lower bound in the first condition). The order is fixed
    before the data, so the claim keeps its confidence after choosing the count."""
    best: tuple[int, float, str] | None = None
    for rule in dict.fromkeys(each["policy"]):
        mine = each[each["policy"] == rule]
        last = None
        for n in sorted(mine[COUNT].unique(), reverse=True):
            at = mine[mine[COUNT] == n]
            if not all(len(_select(at, c)) and _select(at, c)["reached"].all() for c in conditions):
                break
            last = int(n)
        if last is None:
            continue
        low = float(_select(mine[mine[COUNT] == last], conditions[0])["ci_low"].iloc[0])
        if best is None or (last, -low) < (best[0], -best[1]):
            best = (last, low, str(rule))
    return (best[0], best[2]) if best is not None else (None, None)


def _answer_rule(
    rows: pd.DataFrame, each: pd.DataFrame, answer: int | None, rule: str | None
) -> pd.DataFrame:
    """``rows`` with the answer's points (no breakdowns) showing the answer's rule, whose
    sequence reached them, instead of the rule with the highest lower bound there."""
    if answer is None:
        return rows
    mine = each[(each[COUNT] == answer) & (each["policy"] == rule)]
    rest = rows[~rows["point"].isin(mine["point"])]
    return pd.concat([rest, mine]).sort_values("point").reset_index(drop=True)


def selection(rules: int, confidence: float) -> dict[str, Any]:
    """sizing.json's ``selection``: how the count and the rule are chosen so that the answer
    keeps its confidence (the report's method line)."""
    each = selected_confidence(confidence, rules)
    sequence = (
        "Robot counts are tested from the largest down, each at the full level, stopping at "
        "the first count that misses the target (fixed-sequence testing); the answer is the "
        "smallest count of that unbroken run, so it keeps "
        f"{100 * confidence:g} % confidence after choosing the count"
    )
    if rules > 1:
        sequence += (
            f"; each of the {rules} rules is its own sequence, with every interval taken at "
            f"{100 * each:.4g} % (Bonferroni), so picking the rule keeps it too"
        )
    return {
        "rules": rules,
        "method": "fixed-sequence" + (" + bonferroni" if rules > 1 else ""),
        "confidence_each": each,
        "text": sequence + ".",
    }


def _limits(rows: pd.DataFrame, others: Sequence[str]) -> list[dict[str, Any]]:
    out = []
    for path, goal in LIMITS.items():
        if path not in others:
            continue
        rest = [p for p in others if p != path]
        for n in sorted(rows[COUNT].unique()):
            for cond in _conditions(rows, rest):
                at = _select(rows[rows[COUNT] == n], cond)
                hit = at[at["reached"]][path]
                value = (hit.min() if goal == "slowest" else hit.max()) if len(hit) else None
                out.append(
                    {
                        "parameter": path,
                        "goal": goal,
                        COUNT: int(n),
                        **cond,
                        "value": None if value is None else float(value),
                    }
                )
    return out


def _ppas(results: pd.DataFrame, rows: pd.DataFrame) -> tuple[float, float, dict[str, Any]]:
    """(part flow, picks/s of a saturated robot, where) at the smallest count, first condition."""
    first = rows.iloc[0]
    at = results[(results["point"] == first["point"]) & (results["policy"] == first["policy"])]
    n = int(first[COUNT])
    busy = (at["utilisation"] * n).replace(0, math.nan)
    ppas = float((at["throughput"] / busy).mean())
    return float(at["part_flow"].mean()), ppas, {"point": int(first["point"]), COUNT: n}


def _g(row: pd.Series | None) -> dict[str, Any] | None:
    if row is None:
        return None
    return {
        "robots": int(row[COUNT]),
        "gripping_rate_mean": float(row["gripping_rate_mean"]),
        "ci_low": float(row["ci_low"]),
        "ci_high": float(row["ci_high"]),
        "reached": bool(row["reached"]),
        "policy": str(row["policy"]),
    }


def analyse(
    results: pd.DataFrame,
    summary: pd.DataFrame,
    grid: Sequence[str],
    scenario: Scenario,
    target: float,
    confidence: float,
    kpi: KpiChoice = GRIPPING,
) -> dict[str, Any]:
    """The sizing.json mapping of a finished sizing study; with a ``kpi`` other than the
    gripping rate, the target and the rows' ``gripping_rate_mean``, ``ci_low`` and
    ``ci_high`` are on that figure, which ``kpi`` names."""
    rows = point_rows(summary, grid, target, results, confidence, kpi.column)
    rules = int(results["policy"].nunique()) if len(results) else 1
    mtbf_values = sorted(rows[MTBF].unique()) if MTBF in grid else [0.0]
    others = [p for p in grid if p not in (COUNT, MTBF)]
    plain = rows[rows[MTBF] == 0] if MTBF in grid else rows
    failing = rows[rows[MTBF] == mtbf_values[-1]] if mtbf_values[-1] > 0 else None
    conditions = _conditions(plain, others)
    each = rule_rows(results, grid, target, confidence, kpi.column)
    each_plain = each[each[MTBF] == 0] if MTBF in grid else each
    answer, rule = fixed_sequence(each_plain, conditions)
    by_condition = [{**c, "answer": fixed_sequence(each_plain, [c])[0]} for c in conditions]
    flow, ppas, where = _ppas(results, plain.sort_values([COUNT, "point"]))
    n_min = flow / ppas if ppas > 0 else math.nan
    n_rec = math.ceil(n_min * (1 + MARGIN)) if math.isfinite(n_min) else None
    mtbf = float(mtbf_values[-1]) if mtbf_values[-1] > 0 else DEFAULT_MTBF
    mttr = float(scenario.robots.mttr) or DEFAULT_MTTR
    availability = mtbf / (mtbf + mttr)
    worst = each[each[MTBF] == mtbf_values[-1]] if failing is not None else None
    n_fail = fixed_sequence(worst, conditions)[0] if worst is not None else None
    base = _select(each_plain[each_plain["policy"] == rule], conditions[0])
    minus = None
    if answer is not None:  # the same rule with one robot fewer
        m = base[base[COUNT] == answer - 1]
        minus = _g(m.iloc[0]) if len(m) else None
    answer_row = base[base[COUNT] == answer].iloc[0] if answer is not None else None
    out = {
        "target": target,
        "confidence": confidence,
        **({} if kpi.default else {"kpi": kpi.to_json()}),
        "parameter": COUNT,
        "rows": _records(_answer_rule(rows, each_plain, answer, rule)),
        "answer": answer,
        "rule": rule,
        "selection": selection(rules, confidence),
        "by_condition": by_condition,
        "limits": _limits(plain, others),
        "rule_of_thumb": {
            "part_flow": flow,
            "ppas": ppas,
            "n_min": n_min,
            "margin": MARGIN,
            "n_recommended": n_rec,
            "measured_at": where,
        },
        "breakdown": {
            "mtbf": mtbf,
            "mttr": mttr,
            "availability": availability,
            "assumed": scenario.robots.mtbf == 0,
            "n_with_failures": n_fail,
            "n_min_with_failures": n_min / availability if math.isfinite(n_min) else None,
            "n_minus_1": minus,
        },
    }
    out["text"] = describe(out, _g(answer_row), conditions[0] if others else {}, kpi)
    return out


def showcase_spec(plan: StudyPlan, sizing: dict[str, Any]) -> RunSpec:
    """The run the report shows up close: the answer's count (else the largest) without
    breakdowns, the best policy there, replication 0."""
    rows = pd.DataFrame(sizing["rows"])
    plain = rows[rows[MTBF] == 0] if MTBF in rows else rows
    n = sizing["answer"] if sizing["answer"] is not None else int(plain[COUNT].max())
    row = plain[plain[COUNT] == n].iloc[0]
    point, policy = int(row["point"]), str(row["policy"])
    return next(
        s for s in plan.specs() if s.point == point and s.policy == policy and s.replication == 0
    )


def _records(frame: pd.DataFrame) -> list[dict[str, Any]]:
    return [
        {k: (v.item() if hasattr(v, "item") else v) for k, v in r.items()}
        for r in frame.to_dict(orient="records")
    ]


def describe(
    s: dict[str, Any],
    at_answer: dict[str, Any] | None,
    base: dict[str, Any],
    kpi: KpiChoice = GRIPPING,
) -> str:
    """The sizing answer in plain words (on the ``kpi`` figure)."""
    conf = f"{100 * s['confidence']:g} %"
    where = ""
    if len(s["by_condition"]) > 1:
        where = " in every swept condition"
    if s["answer"] is None:
        goal = f"{s['target']:g} %" if kpi.default else f"a {s['target']:g} % {kpi.noun}"
        first = f"No robot count in the study reaches {goal} with {conf} confidence."
    else:
        lb = f" (lower bound {at_answer['ci_low']:.1f} %)" if at_answer else ""
        rule = f" running {s['rule']}" if s.get("rule") else ""
        first = (
            f"{s['answer']} robots{rule} reach a {s['target']:g} % {kpi.noun} with {conf} "
            f"confidence{where}{lb}."
        )
    r = s["rule_of_thumb"]
    rot = (
        f" Rule of thumb: N_min = f_p / PPas = {r['part_flow']:.2f} / {r['ppas']:.2f} = "
        f"{r['n_min']:.2f}, so {r['n_recommended']} robots with a {100 * r['margin']:g} % margin."
        if r["n_recommended"] is not None
        else ""
    )
    b = s["breakdown"]
    fail = (
        f" With breakdowns (MTBF {b['mtbf']:g} s, MTTR {b['mttr']:g} s"
        f"{', assumed' if b['assumed'] else ''}; availability {100 * b['availability']:.1f} %), "
        + (
            f"{b['n_with_failures']} robots are needed."
            if b["n_with_failures"] is not None
            else "no count in the study reaches the target."
        )
    )
    m = b["n_minus_1"]
    down = (
        f" With one robot down ({m['robots']} working), {kpi.short} = "
        f"{m['gripping_rate_mean']:.1f} % "
        f"[{m['ci_low']:.1f}, {m['ci_high']:.1f}]."
        if m
        else ""
    )
    return first + rot + fail + down


def check_size(
    scenario: Scenario,
    target: float | None,
    confidence: float,
    policies: Sequence[str] | None = None,
    replications: int | None = None,
    layout: str = "extend",
) -> float:
    """The target of a sizing study of ``scenario``, every setting checked (target,
    confidence, layout, every robot count's line and policy), before its folder is touched."""
    sweep = scenario.sweep
    target = target if target is not None else (sweep.target if sweep else None)
    if target is None:
        raise StudyError("--target: no target gripping rate; give --target 99 or sweep.target")
    if not 0 < target <= 100:
        raise StudyError(f"--target: {target:g} is not allowed; give a percentage in (0, 100]")
    if not 0 < confidence < 1:
        raise StudyError(f"--confidence: {confidence:g} is not allowed; give 0 < c < 1")
    line, grid = sizing_setup(scenario, sweep.grid if sweep else {}, layout)
    plan = build_plan(line, grid=grid, policies=policies, replications=replications)
    if layout == "share":
        share_layout(plan, scenario)
    return float(target)


def run_size(
    scenario: Scenario,
    out: Path,
    target: float | None,
    options: Options,
    policies: Sequence[str] | None = None,
    replications: int | None = None,
    layout: str = "extend",
) -> tuple[Tables, dict[str, Any]]:
    """Run a sizing study into ``out``; returns its tables and the sizing.json mapping."""
    sweep = scenario.sweep
    target = target if target is not None else (sweep.target if sweep else None)
    if target is None:
        raise StudyError("--target: no target gripping rate; give --target 99 or sweep.target")
    if not 0 < target <= 100:
        raise StudyError(f"--target: {target:g} is not allowed; give a percentage in (0, 100]")
    if not 0 < options.confidence < 1:
        raise StudyError(f"--confidence: {options.confidence:g} is not allowed; give 0 < c < 1")
    line, grid = sizing_setup(scenario, sweep.grid if sweep else {}, layout)
    plan = build_plan(line, grid=grid, policies=policies, replications=replications)
    if layout == "share":
        plan = share_layout(plan, scenario)
    # study.json keeps what is simulated (the layout) apart from how the runs are read (the
    # target and confidence): another --target or --confidence reuses every stored run
    analysis: dict[str, Any] = {"target": target, "confidence": options.confidence}
    kpi = options.kpi
    if not kpi.default:  # how the runs are read, too: another --kpi reuses every stored run
        analysis["kpi"] = kpi.name
        if plan.precision is not None:  # -r auto: the half-width of the figure sized on
            plan = replace(plan, precision=replace(plan.precision, kpi=kpi.column))
    session = open_session(out, plan, "size", options, {"layout": layout, "analysis": analysis})
    plan, rows = run_plan(session, plan)
    tables = finish(session, plan, "size", rows, {"layout": layout, **analysis})
    sizing = analyse(
        tables.results,
        tables.summary,
        list(plan.grid),
        plan.scenario,
        target,
        options.confidence,
        kpi,
    )
    sizing["layout"] = layout_summary(plan, layout)
    sizing["layout"]["text"] = layout_text(sizing["layout"], scenario)
    sizing["text"] = sizing["layout"]["text"] + " " + sizing["text"]
    shown = replace(showcase_spec(plan, sizing), engine=options.engine)
    write_records(out, shown)
    write_json(sizing, out / "sizing.json", keep_nan=True)
    # not in sizing.json: the answer's line, rule and first seed (--write-scenario's)
    sizing["showcase_spec"] = shown if sizing["answer"] is not None else None
    return tables, sizing
