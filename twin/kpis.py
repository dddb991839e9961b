"""KPIs of one run, computed from its record tables over the measurement window.

The window is [warm-up, duration): a part counts if it was fed in it, and the run drains so
every such part has an outcome. Time-based figures (utilisation, NooP, down time) are the
robots' state spans clipped to the same window.

Robots are numbered from 1 in the record tables, as everywhere a person reads them.

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

``welch_gripping_rate`` is G over time for Welch's warm-up plot: the feeding period, warm-up
included, cut into ``WELCH_BINS`` bins by time fed (NaN for a bin no part was fed in).
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from typing import Any

import numpy as np
import pandas as pd

from twin.decision import RobotSpec
from twin.geometry import move_time

STATES = ("busy", "noop", "wait", "blocked", "down")
WELCH_BINS = 60  # the feeding period [0, duration) in this many bins, warm-up included


def clipped(
    start: pd.Series | np.ndarray, end: pd.Series | np.ndarray, w0: float, w1: float
) -> np.ndarray:
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


def state_times(
    parts: pd.DataFrame, spans: pd.DataFrame, n: int, w0: float, w1: float
) -> np.ndarray:
    """(n robots x STATES) seconds spent in each state inside the window."""
    out = np.zeros((n, len(STATES)))
    picked = parts[parts["outcome"] == "picked"]
    if len(picked):
        busy = clipped(picked["decided_at"], picked["placed_at"], w0, w1)
        np.add.at(out[:, 0], picked["robot"].to_numpy(dtype=np.int64) - 1, busy)
    if len(spans):
        lengths = clipped(spans["start"], spans["end"], w0, w1)
        rob = spans["robot"].to_numpy(dtype=np.int64) - 1
        for j, state in enumerate(STATES):
            mask = (spans["state"] == ("interrupted" if state == "busy" else state)).to_numpy()
            np.add.at(out[:, j], rob[mask], lengths[mask])
        # blocked time sits inside the busy cycle span: move it out of busy
        out[:, 0] -= out[:, STATES.index("blocked")]
    return out


def welch_series(parts: pd.DataFrame, duration: float, bins: int = WELCH_BINS) -> list[float]:
    """G (%) of the parts fed in each of ``bins`` equal bins of [0, duration)."""
    fed = parts["fed_at"].to_numpy(dtype=float)
    inside = (fed >= 0) & (fed < duration)
    k = np.minimum((fed[inside] / duration * bins).astype(np.int64), bins - 1)
    picked = (parts["outcome"] == "picked").to_numpy()[inside]
    n = np.bincount(k, minlength=bins)
    hit = np.bincount(k, weights=picked.astype(float), minlength=bins)
    with np.errstate(invalid="ignore", divide="ignore"):
        g = np.where(n > 0, 100.0 * hit / np.maximum(n, 1), np.nan)
    return [round(float(x), 3) for x in g]


def compute_kpis(
    parts: pd.DataFrame,
    spans: pd.DataFrame,
    specs: Sequence[RobotSpec],
    warmup: float,
    duration: float,
) -> dict[str, Any]:
    """The KPI dictionary of one run (see the module docstring for definitions)."""
    n = len(specs)
    w0, w1 = warmup, duration
    span = w1 - w0
    win = parts[(parts["fed_at"] >= w0) & (parts["fed_at"] < w1)]
    presented = len(win)
    is_picked = (win["outcome"] == "picked").to_numpy()
    picked = int(is_picked.sum())
    robot_of = win["robot"].to_numpy(dtype=float, na_value=np.nan) - 1  # 0-based here
    picks = np.bincount(robot_of[is_picked].astype(np.int64), minlength=n)[:n]
    states = state_times(parts, spans, n, w0, w1)
    nominal = np.array([robot_capacity(s) for s in specs])
    cycle_all = (win["placed_at"] - win["decided_at"]).to_numpy()
    busy = states[:, 0]
    worked = (busy > 0) & (picks > 0)
    caps = np.where(worked, picks / np.where(worked, busy, 1.0), nominal)
    flow = presented / span
    max_tp = min(flow, float(caps.sum()))
    tp = picked / span
    cycles = cycle_all[is_picked]
    lost = int(np.sum(~is_picked))
    robots = []
    for i in range(n):
        mine = cycle_all[is_picked & (robot_of == i)]
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
                "passed_on": int(np.sum(robot_of[is_picked] > i)),
                "lost": lost,
                "cycle_time_mean": float(mine.mean()) if len(mine) else math.nan,
                "capacity": float(caps[i]),
                "nominal_capacity": float(nominal[i]),
            }
        )
    noops = spans[(spans["state"] == "noop") & (spans["start"] >= w0) & (spans["start"] < w1)]
    rules = win.loc[is_picked, "rule"].fillna("?").value_counts().to_dict()
    rules["NooP"] = len(noops)
    return {
        "gripping_rate": 100.0 * picked / presented if presented else math.nan,
        "parts_presented": presented,
        "parts_picked": picked,
        "parts_missed": presented - picked,  # lost to the return conveyor
        "throughput": tp,
        "part_flow": flow,
        "max_throughput": max_tp,
        "efficiency": tp / max_tp if max_tp > 0 else math.nan,
        "utilisation": float(states[:, 0].sum() / (span * n)),
        "cycle_time_mean": float(cycles.mean()) if len(cycles) else math.nan,
        "cycle_time_p50": float(np.percentile(cycles, 50)) if len(cycles) else math.nan,
        "cycle_time_p95": float(np.percentile(cycles, 95)) if len(cycles) else math.nan,
        "cycle_time_max": float(cycles.max()) if len(cycles) else math.nan,
        "decisions": {str(k): int(v) for k, v in sorted(rules.items())},
        "window": [w0, w1],
        "welch_gripping_rate": welch_series(parts, w1),
        "robots": robots,
    }


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
    return row
