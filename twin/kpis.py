"""KPIs of one run, computed from its records as plain arrays over the measurement window.

This is the one implementation of the KPIs: the SimPy run passes its
:class:`~twin.records.Recorder`'s records (:func:`recorder_records`), the fast engine its
arrays (:meth:`twin.fast.engine.FastLine.kpi_records`), and record tables read back (tests,
files) are turned into the same arrays once (:func:`table_records`). Inside, robots are
indexed from 0; the KPI dictionary numbers them from 1, as everywhere a person reads them.

The window is [warm-up, duration): a part counts if it was fed in it, and the run drains so
every such part has an outcome. Time-based figures (utilisation, NooP, down time) are the
robots' state spans clipped to the same window.

Efficiency is throughput over ``max_throughput`` = min(part flow presented, the robots'
measured cycle rate), where a robot's cycle rate (``capacity``) is its picks in the window per
second of its busy time there (moving, gripping, placing): what it picks while it works. So
efficiency never passes 100 % and a line whose robots are never idle reads about 100 %. A
robot that never worked in the window counts at its ``nominal_capacity``, 1 / its shortest
possible cycle: pick + place + a round trip between its bin and the nearest point of the
belt (the upper edge below the bin) at arm speed.

Parts a robot did not pick are split into ``passed_on`` (left its workspace unpicked and were
picked by a robot downstream) and ``lost`` (left its workspace unpicked and reached the return
conveyor: the line's ``parts_missed``).

On a line with kinds of part (feeder.kinds), a kind no robot picks passes on by design: its
parts are counted apart (``parts_passed_by_design``) and left out of G and of every figure
built on the parts presented. ``kinds`` gives each kind's figures (presented, picked, lost,
gripping rate, value) and ``value_rate`` the % of the value presented (every kind's) that was
gripped. Lines of one kind have none of these keys (their KPIs are as before kinds existed).

``welch_gripping_rate`` is G over time for Welch's warm-up plot: the feeding period, warm-up
included, cut into ``WELCH_BINS`` bins by time fed (NaN for a bin no part was fed in).
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Any

import numpy as np

from pnp_twin.twin.decision import RobotSpec
from pnp_twin.twin.geometry import move_time
from pnp_twin.twin.outfeed import OutfeedPlan

if TYPE_CHECKING:
    import pandas as pd

    from pnp_twin.twin.records import Recorder

STATES = ("busy", "noop", "wait", "blocked", "down")
SPAN_STATES = ("wait", "interrupted", "noop", "blocked", "down", "holding")
"""The states a span records, in the order of :attr:`SpanRecords.state`'s codes."""
PERCENTILES = (50, 95)  # of the cycle times: cycle_time_p50 and cycle_time_p95
WELCH_BINS = 60  # the feeding period [0, duration) in this many bins, warm-up included


@dataclass(frozen=True)
class PartRecords:
    """One entry per part fed, in feeding order. Where a part was not picked (``picked``
    false: it reached the return conveyor) its other entries but ``fed_at`` are not read."""

    fed_at: np.ndarray  # float seconds
    robot: np.ndarray  # int, 0-based: the robot that picked it
    rule: np.ndarray  # int code into ``rule_names``; -1 for a pick without a rule name ("?")
    rule_names: tuple[str, ...]
    decided_at: np.ndarray  # float
    placed_at: np.ndarray  # float
    picked: np.ndarray  # bool
    kind: np.ndarray | None = None  # int kind codes (None: one kind)
    counted: np.ndarray | None = None  # bool: in G's scope (None: every part)
    container: np.ndarray | None = None  # int: the outfeed container placed into, -1 none
    held_at: np.ndarray | None = None  # float: when a hold for a free slot began, NaN none


@dataclass(frozen=True)
class KindTable:
    """The kinds of part of a line (:meth:`twin.plan.LinePlan.kind_table`), by code."""

    names: tuple[str, ...]
    values: tuple[float, ...]
    targeted: tuple[bool, ...]  # some robot picks it

    def with_records(self, parts: PartRecords, codes: np.ndarray) -> PartRecords:
        """``parts`` with their kind codes, and the parts G counts (targeted kinds) when
        some kind is not targeted."""
        counted = None
        if not all(self.targeted):
            counted = np.asarray(self.targeted, dtype=bool)[codes]
        return replace(parts, kind=codes, counted=counted)


@dataclass(frozen=True)
class SpanRecords:
    """One entry per robot state span, in the order the run recorded them."""

    robot: np.ndarray  # int, 0-based
    state: np.ndarray  # int code into SPAN_STATES
    start: np.ndarray  # float
    end: np.ndarray  # float


def recorder_records(
    rec: Recorder, fed_at: Sequence[float] | np.ndarray
) -> tuple[PartRecords, SpanRecords]:
    """The KPIs' arrays of a SimPy run's Recorder (``fed_at``: the belt's feed times)."""
    names = tuple(sorted({r for r in rec.rule if r is not None}))
    code = {name: i for i, name in enumerate(names)}
    rules = np.fromiter((-1 if r is None else code[r] for r in rec.rule), np.int64, len(rec.rule))
    parts = PartRecords(
        np.asarray(fed_at, dtype=float),
        np.asarray(rec.robot, dtype=np.int64),
        rules,
        names,
        np.asarray(rec.decided_at, dtype=float),
        np.asarray(rec.placed_at, dtype=float),
        ~np.isnan(np.asarray(rec.picked_at, dtype=float)),
    )
    if rec.outfeed:
        container = np.asarray(rec.container, dtype=np.int64)
        parts = replace(parts, container=container, held_at=np.asarray(rec.held_at, dtype=float))
    state = {name: i for i, name in enumerate(SPAN_STATES)}
    spans = rec.spans
    return parts, SpanRecords(
        np.fromiter((s[0] for s in spans), np.int64, len(spans)),
        np.fromiter((state[s[1]] for s in spans), np.int64, len(spans)),
        np.fromiter((s[2] for s in spans), float, len(spans)),
        np.fromiter((s[3] for s in spans), float, len(spans)),
    )


def table_records(parts: pd.DataFrame, spans: pd.DataFrame) -> tuple[PartRecords, SpanRecords]:
    """The KPIs' arrays of record tables (``Recorder.parts_frame`` / ``spans_frame``)."""
    picked = (parts["outcome"] == "picked").to_numpy()
    robot = parts["robot"].to_numpy(dtype=float, na_value=np.nan)
    named = parts["rule"].notna().to_numpy()
    labels = [str(r) for r in parts["rule"].to_numpy(dtype=object)]  # read where named only
    names = tuple(sorted({r for r, ok in zip(labels, named & picked, strict=True) if ok}))
    code = {name: i for i, name in enumerate(names)}
    rules = [code.get(r, -1) if ok else -1 for r, ok in zip(labels, named, strict=True)]
    part_records = PartRecords(
        parts["fed_at"].to_numpy(dtype=float),
        np.where(picked, np.nan_to_num(robot, nan=0.0) - 1, -1).astype(np.int64),
        np.array(rules, dtype=np.int64),
        names,
        parts["decided_at"].to_numpy(dtype=float),
        parts["placed_at"].to_numpy(dtype=float),
        picked,
    )
    if "container" in parts.columns:  # a line with an outfeed
        part_records = replace(
            part_records,
            container=parts["container"].to_numpy(dtype=float, na_value=-1.0).astype(np.int64),
            held_at=parts["held_at"].to_numpy(dtype=float),
        )
    state = {name: i for i, name in enumerate(SPAN_STATES)}
    return part_records, SpanRecords(
        spans["robot"].to_numpy(dtype=np.int64) - 1,
        np.array([state[s] for s in spans["state"]], dtype=np.int64),
        spans["start"].to_numpy(dtype=float),
        spans["end"].to_numpy(dtype=float),
    )


def clipped(start: np.ndarray, end: np.ndarray, w0: float, w1: float) -> np.ndarray:
    """Length of each interval [start, end] inside [w0, w1]."""
    s = np.maximum(np.asarray(start, dtype=float), w0)
    e = np.minimum(np.asarray(end, dtype=float), w1)
    return np.clip(e - s, 0.0, None)


def robot_capacity(spec: RobotSpec) -> float:
    """Picks per second of the shortest possible cycle (see module docstring)."""
    gap = max(spec.bin[1] - spec.belt_width, 0.0)
    trip = 2.0 * move_time(gap, spec.arm_speed, spec.acceleration)
    return (
        1.0 / (spec.pick_time + spec.place_time + trip)
        if trip + spec.pick_time + spec.place_time > 0
        else math.inf
    )


def state_times(parts: PartRecords, spans: SpanRecords, n: int, w0: float, w1: float) -> np.ndarray:
    """(n robots x STATES) seconds spent in each state inside the window."""
    out = np.zeros((n, len(STATES)))
    picked = parts.picked
    if picked.any():
        placed = parts.placed_at[picked]  # NaN: still held for a slot when the run ended
        busy = clipped(parts.decided_at[picked], np.where(np.isnan(placed), w1, placed), w0, w1)
        np.add.at(out[:, 0], parts.robot[picked], busy)
    if len(spans.state):
        lengths = clipped(spans.start, spans.end, w0, w1)
        for j, state in enumerate(STATES):
            mask = spans.state == SPAN_STATES.index("interrupted" if state == "busy" else state)
            if state == "blocked":  # holding a part for a free outfeed slot blocks the robot
                mask |= spans.state == SPAN_STATES.index("holding")
            np.add.at(out[:, j], spans.robot[mask], lengths[mask])
        # blocked time sits inside the busy cycle span: move it out of busy
        out[:, 0] -= out[:, STATES.index("blocked")]
    return out


@dataclass(frozen=True)
class KpiTally:
    """The sums over a run's records that the KPIs are made of (one pass over the records;
    the fast engine fills it in one compiled pass: :func:`twin.fast.tally.tally`)."""

    presented: int  # parts fed in the window
    picked: int  # of those, picked
    picks: np.ndarray  # (n,) int: picks of the window per robot
    states: np.ndarray  # (n, STATES) seconds in each state inside the window
    cycles: np.ndarray  # cycle times (placed - decided) of the window's picks, in part order
    robot_cycles: np.ndarray  # the same grouped by robot (part order within a robot)
    robot_starts: np.ndarray  # (n + 1,) int: robot i's are robot_cycles[starts[i]:starts[i+1]]
    rules: np.ndarray  # (len(rule_names) + 1,) int: the window's picks per rule code + 1
    noops: int  # NooPs started in the window
    welch_parts: np.ndarray  # (WELCH_BINS,) int: parts fed per bin of [0, duration)
    welch_picked: np.ndarray  # (WELCH_BINS,) float: of those, picked
    spare: np.ndarray | None = None  # a copy of cycles the quantiles may reorder (None: copy)
    percentiles: tuple[float, float] | None = None  # of the cycles at PERCENTILES, if taken


def tally(parts: PartRecords, spans: SpanRecords, n: int, w0: float, w1: float) -> KpiTally:
    """:class:`KpiTally` of the records (numpy) for window [w0, w1) (w1: the duration)."""
    win = (parts.fed_at >= w0) & (parts.fed_at < w1)
    if parts.counted is not None:  # kinds no robot picks pass on by design: not counted
        win &= parts.counted
    is_picked = parts.picked[win]
    robot_of = np.where(parts.picked, parts.robot, -1)[win]
    cycles = (parts.placed_at[win] - parts.decided_at[win])[is_picked]
    mine = robot_of[is_picked]
    cycled = mine  # the robots of the cycles
    if np.isnan(cycles).any():  # parts still held for an outfeed slot at the end: no cycle
        cycled = mine[~np.isnan(cycles)]
        cycles = cycles[~np.isnan(cycles)]
    order = np.argsort(cycled, kind="stable")
    start = spans.start
    noops = (spans.state == SPAN_STATES.index("noop")) & (start >= w0) & (start < w1)
    fed = parts.fed_at
    inside = (fed >= 0) & (fed < w1)
    if parts.counted is not None:
        inside &= parts.counted
    k = np.minimum((fed[inside] / w1 * WELCH_BINS).astype(np.int64), WELCH_BINS - 1)
    return KpiTally(
        presented=int(win.sum()),
        picked=int(is_picked.sum()),
        picks=np.bincount(mine, minlength=n)[:n],
        states=state_times(parts, spans, n, w0, w1),
        cycles=cycles,
        robot_cycles=cycles[order],
        robot_starts=np.searchsorted(cycled[order], np.arange(n + 1)),
        rules=np.bincount(parts.rule[win & parts.picked] + 1, minlength=len(parts.rule_names) + 1),
        noops=int(noops.sum()),
        welch_parts=np.bincount(k, minlength=WELCH_BINS),
        welch_picked=np.bincount(
            k, weights=parts.picked[inside].astype(float), minlength=WELCH_BINS
        ),
    )


def compute_kpis(
    parts: PartRecords,
    spans: SpanRecords,
    specs: Sequence[RobotSpec],
    warmup: float,
    duration: float,
    kinds: KindTable | None = None,
    outfeed: OutfeedPlan | None = None,
) -> dict[str, Any]:
    """The KPI dictionary of one run (see the module docstring for definitions); with
    ``kinds`` (a line with feeder.kinds; ``parts`` carry their kind codes) the per-kind
    figures too; with ``outfeed`` (``parts`` carry their containers) the outfeed's."""
    sums = tally(parts, spans, len(specs), warmup, duration)
    kpis = tally_kpis(sums, parts.rule_names, specs, warmup, duration)
    if kinds is not None:
        kpis.update(kind_kpis(kinds, parts, warmup, duration))
    if outfeed is not None:
        assert parts.container is not None and parts.held_at is not None
        figures = outfeed_kpis(
            outfeed, parts, parts.container, parts.held_at, spans, len(specs), warmup, duration
        )
        for robot, hold in zip(kpis["robots"], figures.pop("robot_hold"), strict=True):
            robot["hold"] = hold
        robots = kpis.pop("robots")
        kpis.update(figures)
        kpis["robots"] = robots  # last, as on every line
    return kpis


def kind_kpis(kinds: KindTable, parts: PartRecords, w0: float, w1: float) -> dict[str, Any]:
    """``value_rate``, ``parts_passed_by_design`` and ``kinds``: each kind's figures over the
    window (see the module docstring)."""
    assert parts.kind is not None, "per-kind KPIs need the parts' kind codes"
    win = (parts.fed_at >= w0) & (parts.fed_at < w1)
    codes = parts.kind[win]
    picked = parts.picked[win]
    presented = np.bincount(codes, minlength=len(kinds.names))
    gripped = np.bincount(codes[picked], minlength=len(kinds.names))
    out: dict[str, dict[str, Any]] = {}
    for c, name in enumerate(kinds.names):
        n, got, value, targeted = (
            int(presented[c]),
            int(gripped[c]),
            kinds.values[c],
            kinds.targeted[c],
        )
        out[name] = {
            "targeted": targeted,
            "value": value,
            "parts_presented": n,
            "parts_picked": got,
            "parts_lost": n - got if targeted else 0,
            "parts_passed_by_design": 0 if targeted else n,
            "gripping_rate": 100.0 * got / n if n and targeted else math.nan,
            "value_presented": value * n,
            "value_picked": value * got,
        }
    worth = math.fsum(k["value_presented"] for k in out.values())
    taken = math.fsum(k["value_picked"] for k in out.values())
    return {
        "value_rate": 100.0 * taken / worth if worth > 0 else math.nan,
        "parts_passed_by_design": sum(k["parts_passed_by_design"] for k in out.values()),
        "kinds": out,
    }


def outfeed_kpis(
    plan: OutfeedPlan,
    parts: PartRecords,
    container: np.ndarray,
    held_at: np.ndarray,
    spans: SpanRecords,
    n: int,
    w0: float,
    w1: float,
) -> dict[str, Any]:
    """The outfeed's figures over the window (a line with [outfeed]): containers that
    entered in it, how many left full, the slots filled in them per second, the parts of
    the window that waited for a slot, the seconds robots held parts (line and per robot)
    and the parts still held when the run ended."""
    span = w1 - w0
    n_slots = plan.n_slots
    entered = np.asarray(plan.times)
    inside = np.flatnonzero((entered >= w0) & (entered < w1))
    placed = container >= 0
    filled = np.bincount(container[placed], minlength=len(entered))[: len(entered)]
    full = int((filled[inside] == n_slots).sum())
    win = (parts.fed_at >= w0) & (parts.fed_at < w1)
    holding = spans.state == SPAN_STATES.index("holding")
    held_s = np.zeros(n)
    np.add.at(held_s, spans.robot[holding], clipped(spans.start, spans.end, w0, w1)[holding])
    boxes = len(inside)
    return {
        "containers": boxes,
        "containers_full": full,
        "containers_unfilled": boxes - full,  # left the last robot's reach with a free slot
        "fill_rate": 100.0 * full / boxes if boxes else math.nan,
        "slots_filled_per_s": float(filled[inside].sum()) / span,
        "parts_held": int((win & ~np.isnan(held_at)).sum()),
        "parts_held_at_end": int((win & parts.picked & ~placed).sum()),
        "hold_time": float(held_s.sum()),
        "hold": float(held_s.sum() / (span * n)),
        "robot_hold": (held_s / span).tolist(),
    }


def tally_kpis(
    sums: KpiTally,
    rule_names: Sequence[str],
    specs: Sequence[RobotSpec],
    warmup: float,
    duration: float,
) -> dict[str, Any]:
    """The KPI dictionary of a run's :class:`KpiTally` (``rule_names``: the rule codes')."""
    n = len(specs)
    w0, w1 = warmup, duration
    span = w1 - w0
    presented = sums.presented
    picked = sums.picked
    picks = sums.picks
    states = sums.states
    nominal = np.array([robot_capacity(s) for s in specs])
    busy = states[:, 0]
    worked = (busy > 0) & (picks > 0)
    caps = np.where(worked, picks / np.where(worked, busy, 1.0), nominal)
    flow = presented / span
    max_tp = min(flow, float(caps.sum()))
    tp = picked / span
    cycles = sums.cycles
    lost = presented - picked
    starts = sums.robot_starts.tolist()
    later = [  # picks by the robots downstream of robot i (their x-range starts past its end)
        int(sum(int(picks[j]) for j in range(n) if specs[j].workspace[0] >= specs[i].workspace[1]))
        for i in range(n)
    ]
    robots = []
    for i in range(n):
        mine = sums.robot_cycles[starts[i] : starts[i + 1]]
        robots.append(
            {
                "robot": i + 1,
                "workspace": list(specs[i].workspace),
                "picks": int(picks[i]),
                "throughput": float(picks[i] / span),
                "utilisation": float(states[i, 0] / span),
                "noop": float(states[i, 1] / span),
                "wait": float(states[i, 2] / span),
                "blocked": float(states[i, 3] / span),
                "down": float(states[i, 4] / span),
                "availability": float(1.0 - states[i, 4] / span),
                "passed_on": int(later[i]),
                "lost": lost,
                "cycle_time_mean": float(mine.mean()) if len(mine) else math.nan,
                "capacity": float(caps[i]),
                "nominal_capacity": float(nominal[i]),
            }
        )
    if sums.percentiles is not None:  # taken already (np.percentile's doubles)
        p50, p95 = sums.percentiles
    elif len(cycles):  # on a spare copy when there is one (same values: same quantiles)
        spare = sums.spare
        quantiles = np.percentile(
            cycles if spare is None else spare, PERCENTILES, overwrite_input=spare is not None
        )
        p50, p95 = quantiles.tolist()
    return {
        "gripping_rate": 100.0 * picked / presented if presented else math.nan,
        "parts_presented": presented,
        "parts_picked": picked,
        "parts_missed": presented - picked,  # lost to the return conveyor
        "throughput": tp,
        "part_flow": flow,
        "max_throughput": max_tp,
        # <= 1 in exact arithmetic; the rounding of the capacities' sum can pass it by an ulp
        "efficiency": min(tp / max_tp, 1.0) if max_tp > 0 else math.nan,
        "utilisation": float(states[:, 0].sum() / (span * n)),
        "cycle_time_mean": float(cycles.mean()) if len(cycles) else math.nan,
        "cycle_time_p50": p50 if len(cycles) else math.nan,
        "cycle_time_p95": p95 if len(cycles) else math.nan,
        "cycle_time_max": float(cycles.max()) if len(cycles) else math.nan,
        "decisions": _decisions(sums, rule_names),
        "window": [w0, w1],
        "welch_gripping_rate": _welch(sums),
        "robots": robots,
    }


def _decisions(sums: KpiTally, rule_names: Sequence[str]) -> dict[str, int]:
    """Picks of the window by rule ("?" without a name) and NooPs that started in it."""
    labels = ("?", *rule_names)
    rules: dict[str, int] = {}
    for c in np.flatnonzero(sums.rules).tolist():
        rules[labels[c]] = rules.get(labels[c], 0) + int(sums.rules[c])
    rules["NooP"] = sums.noops
    return {k: rules[k] for k in sorted(rules)}


def _welch(sums: KpiTally) -> list[float]:
    n, hit = sums.welch_parts, sums.welch_picked
    with np.errstate(invalid="ignore", divide="ignore"):
        g = np.where(n > 0, 100.0 * hit / np.maximum(n, 1), np.nan)
    return [round(x, 3) for x in g.tolist()]


def table_kpis(
    parts: pd.DataFrame,
    spans: pd.DataFrame,
    specs: Sequence[RobotSpec],
    warmup: float,
    duration: float,
    kinds: KindTable | None = None,
    outfeed: OutfeedPlan | None = None,
) -> dict[str, Any]:
    """:func:`compute_kpis` of record tables (``Recorder.parts_frame`` / ``spans_frame``)."""
    part_records, span_records = table_records(parts, spans)
    if kinds is not None:
        code = {name: c for c, name in enumerate(kinds.names)}
        codes = np.array([code[k] for k in parts["kind"]], dtype=np.int64)
        part_records = kinds.with_records(part_records, codes)
    return compute_kpis(part_records, span_records, specs, warmup, duration, kinds, outfeed)


def flat_kpis(kpis: dict[str, Any]) -> dict[str, Any]:
    """One flat row: scalar KPIs, ``r{i}_{name}`` per robot, ``rule_{name}`` per rule."""
    row = {k: v for k, v in kpis.items() if not isinstance(v, dict | list)}
    if "welch_gripping_rate" in kpis:  # one text cell: the series as JSON (NaN for empty bins)
        row["welch_gripping_rate"] = json.dumps(kpis["welch_gripping_rate"])
    for r in kpis["robots"]:
        for k, v in r.items():
            if k not in ("robot", "workspace"):
                row[f"r{r['robot']}_{k}"] = v
    for rule, count in kpis["decisions"].items():
        row[f"rule_{rule}"] = count
    for name, figures in kpis.get("kinds", {}).items():
        for k, v in figures.items():
            if k != "targeted":  # a setting of the line, not a figure of the run
                row[f"kind_{name}_{k}"] = v
    return row
