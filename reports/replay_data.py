"""What a replay shows, rebuilt from a run's records alone: the line, the parts, the tools.

A run records each part (fed, picked, placed, lost; its robot, container and slot) and each
robot's long states (down, blocked by a box change, holding a part for a free slot, waiting
for the others); nothing records where a tool is. The tool's path follows from the model
(docs/model.md, "One pick-and-place cycle") and those records: from where the last cycle left
it (the robot's base at t = 0), it moves straight at arm speed (trapezoidal with an
acceleration limit) from ``decided_at`` to the part's position at ``picked_at``, grips for the
kind's pick time, then moves to its bin and places (until ``placed_at``), or, onto an outfeed,
holds for ``hold_time``, moves to its slot where the slot is at ``placed_at - place_time`` and
moves with the slot while it releases. Box changes follow from the bins' capacity: every
``capacity``-th part booked into a chute starts one, ``change_time`` s from its place's end.

:func:`replay_data` turns the records of a window of the run into one JSON-ready dict (the
page's replay draws it, :mod:`reports.replay_page`); :func:`parts_at` and :func:`tools_at`
compute from that dict where every part and tool is at an instant, as the page draws them
(the GIF export and the tests read them).

One thing the records do not say: where a tool stopped when ``t_any`` interrupted its
approach (the released part is not recorded). The tool is then drawn still during the
interrupted approach, and its next approach is drawn as a straight move at the pace that
meets the part on time.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd

from pnp_twin.reports.record_figures import recorded_scenario
from pnp_twin.reports.style import PALETTE
from pnp_twin.twin.geometry import move_time, position_along
from pnp_twin.twin.plan import LinePlan

DIGITS = 4  # decimals kept of every time and position (0.1 ms, 0.1 mm)
FATES = ("picked", "lost", "by design")
"""A part's fate code in the data: its index here."""
MOVE, FOLLOW = 0, 1
"""Leg modes: a move from rest to rest at arm speed (then still at its end), or a linear
glide from start to end over the leg (the tool riding with an outfeed slot)."""
STATES = ("down", "blocked", "holding", "wait", "interrupted")
"""The robot states a replay marks (index = the state's code in the data)."""
KIND_COLOURS = ("#f4d35e", "#7bc8f6", "#f28482", "#84dcc6", "#c3a6ff", "#ffb570", "#b5e48c")
ONE_KIND = "#ffffff"


@dataclass(frozen=True)
class Leg:
    """One stretch of a tool's path: from ``start`` at ``t0``; a MOVE ends at rest at ``end``
    (reached at ``t0`` + its move time, at the latest at ``t1``), a FOLLOW glides linearly to
    ``end`` at ``t1``."""

    t0: float
    t1: float
    start: tuple[float, float]
    end: tuple[float, float]
    mode: int = MOVE


def _r(x: float) -> float:
    return round(float(x), DIGITS)


def _pt(p: tuple[float, float]) -> tuple[float, float]:
    return (_r(p[0]), _r(p[1]))


def tool_legs(parts: pd.DataFrame, plan: LinePlan) -> list[list[Leg]]:
    """Each robot's path over the whole run, leg by leg, from the part records."""
    belt = plan.scenario.belt
    v = belt.speed
    code = {name: c for c, name in enumerate(plan.kinds)}
    out: list[list[Leg]] = []
    picked = parts[parts["outcome"] == "picked"].sort_values("decided_at")
    for rp in plan.robots:
        spec = rp.spec
        mine = picked[picked["robot"] == spec.index + 1]
        legs: list[Leg] = []
        tool = rp.base
        for row in mine.itertuples(index=False):
            kind = code.get(str(getattr(row, "kind", "")), 0) if len(plan.kinds) > 1 else 0
            grip = (v * (row.picked_at - row.fed_at), float(row.y))
            dist = math.hypot(grip[0] - tool[0], grip[1] - tool[1])
            on_time = move_time(dist, spec.arm_speed, spec.acceleration)
            paced = on_time <= row.picked_at - row.decided_at + 1e-6
            legs.append(Leg(row.decided_at, row.picked_at, tool, grip, MOVE if paced else FOLLOW))
            leave = row.picked_at + spec.pick_of(kind)
            if plan.outfeed is None:
                legs.append(Leg(leave, max(row.placed_at, leave), grip, spec.bin))
                tool = spec.bin
                continue
            if math.isnan(row.placed_at):  # still held for a slot at the end of the run
                tool = grip
                continue
            of = plan.outfeed
            meet_at = row.placed_at - spec.place_of(kind)
            c, k = int(row.container), int(row.slot)
            meet = (of.slot_x(c, k, meet_at), of.slot_y(k))
            done = (of.slot_x(c, k, row.placed_at), of.slot_y(k))
            legs.append(Leg(leave + float(row.hold_time), meet_at, grip, meet))
            legs.append(Leg(meet_at, row.placed_at, meet, done, FOLLOW))
            tool = done
        out.append(legs)
    return out


def box_changes(parts: pd.DataFrame, plan: LinePlan) -> list[tuple[int, float, float]]:
    """(robot from 0, start, end) of every box change: the ``capacity``-th part booked into
    a chute (robot and kind) fills it; the change runs from that place's end."""
    cap, change = plan.capacity, plan.change_time
    if not cap or plan.outfeed is not None:
        return []
    done = parts[parts["outcome"] == "picked"].sort_values("picked_at")
    out = []
    for (robot, _), group in done.groupby(["robot", "kind"], sort=False):
        for at in group["placed_at"].to_numpy()[cap - 1 :: cap]:
            out.append((int(robot) - 1, float(at), float(at) + change))
    return sorted(out, key=lambda x: x[1])


def _fates(parts: pd.DataFrame, plan: LinePlan) -> np.ndarray:
    untargeted = {k for k, t in zip(plan.kinds, plan.targeted, strict=True) if not t and k}
    fate = np.where(parts["outcome"].to_numpy() == "picked", 0, 1)
    if untargeted and "kind" in parts.columns:
        fate = np.where(parts["kind"].isin(untargeted).to_numpy() & (fate == 1), 2, fate)
    return fate


def _window(scenario: Mapping[str, Any], start: float | None, seconds: float) -> tuple[float, ...]:
    duration = float(scenario.get("duration") or 60.0)
    warmup = float(scenario.get("warmup") or 0.0)
    t0 = warmup if start is None else float(start)
    t0 = min(max(t0, 0.0), max(duration - 0.5, 0.0))
    return t0, min(t0 + max(seconds, 0.5), duration), warmup, duration


def replay_data(
    parts: pd.DataFrame,
    spans: pd.DataFrame,
    scenario: Mapping[str, Any],
    seed: int | None = None,
    start: float | None = None,
    seconds: float = 60.0,
    title: str = "",
) -> dict[str, Any]:
    """The replay of the run whose records these are, over ``seconds`` s from ``start``
    (None: the end of the warm-up), as one JSON-ready dict (see the module docstring)."""
    line = recorded_scenario(dict(scenario))
    plan = LinePlan.of(line, seed)
    t0, t1, warmup, duration = _window(scenario, start, seconds)
    belt = line.belt
    v = belt.speed
    parts = parts.reset_index(drop=True)
    fate = _fates(parts, plan)
    left = parts["left_at"].to_numpy(dtype=float)
    placed = parts["placed_at"].to_numpy(dtype=float)
    gone = np.where(np.isnan(placed), np.where(fate == 0, np.inf, left), placed)
    fed = parts["fed_at"].to_numpy(dtype=float)
    shown = (fed <= t1) & (gone >= t0)
    counted = (fed >= warmup) & (fed < duration) & (fate < 2)
    ends = np.where(fate == 0, parts["picked_at"].to_numpy(dtype=float), left)
    before = counted & (ends < t0)
    sel = parts[shown]
    code = {name: c for c, name in enumerate(plan.kinds)}
    kinds = [code.get(str(k), 0) for k in sel["kind"]] if len(plan.kinds) > 1 else [0] * len(sel)
    robot = sel["robot"].fillna(0).astype(int).to_numpy() - 1
    data: dict[str, Any] = {
        "version": 1,
        "title": title,
        "t0": _r(t0),
        "t1": _r(t1),
        "warmup": warmup,
        "belt": {"length": belt.length, "width": belt.width, "speed": v},
        "robots": [_robot(r.spec, r.base, line, i) for i, r in enumerate(plan.robots)],
        "kinds": [k for k in plan.kinds],
        "kindColours": [
            KIND_COLOURS[c % len(KIND_COLOURS)] if k else ONE_KIND for c, k in enumerate(plan.kinds)
        ],
        "parts": {
            "id": sel["part"].astype(int).tolist(),
            "fed": [_r(x) for x in sel["fed_at"]],
            "y": [_r(x) for x in sel["y"]],
            "kind": kinds,
            "fate": fate[shown].astype(int).tolist(),
            "robot": robot.tolist(),
            "decided": [_nan(x) for x in sel["decided_at"]],
            "picked": [_nan(x) for x in sel["picked_at"]],
            "placed": [_nan(x) for x in sel["placed_at"]],
            "left": [_r(x) for x in sel["left_at"]],
            "counted": counted[shown].astype(int).tolist(),
        },
        "before": {
            "picked": int((before & (fate == 0)).sum()),
            "lost": int((before & (fate == 1)).sum()),
        },
        "legs": [_legs(legs, t0, t1) for legs in tool_legs(parts, plan)],
        "states": _states(spans, box_changes(parts, plan), t0, t1),
        "outfeed": _outfeed(parts, plan, line, t0, t1),
    }
    return data


def _nan(x: float) -> float | None:
    return None if x is None or not math.isfinite(x) else _r(x)


def _robot(spec: Any, base: tuple[float, float], line: Any, i: int) -> dict[str, Any]:
    kinds = [k for k, p in zip(line.kind_names(), spec.picks, strict=False) if p and k]
    return {
        "name": f"R{i + 1}",
        "colour": PALETTE[i % len(PALETTE)],
        "workspace": list(spec.workspace),
        "bin": _pt(spec.bin),
        "base": _pt(base),
        "mount": _pt(spec.mount),
        "side": spec.side,
        "reach": spec.reach,
        "speed": spec.arm_speed,
        "acc": spec.acceleration,
        "kinds": kinds,
    }


def _legs(legs: list[Leg], t0: float, t1: float) -> list[list[float]]:
    """The legs that matter in [t0, t1]: the last one ending before t0 (where the tool
    rests at t0) and every one that ends later and starts by t1."""
    first = 0
    for i, leg in enumerate(legs):
        if leg.t1 < t0:
            first = i
    return [
        [_r(g.t0), _r(g.t1), *_pt(g.start), *_pt(g.end), g.mode] for g in legs[first:] if g.t0 <= t1
    ]


def _states(
    spans: pd.DataFrame, changes: list[tuple[int, float, float]], t0: float, t1: float
) -> list[list[float]]:
    """[robot from 0, state code, start, end] of the marked states overlapping [t0, t1];
    a box change is marked as state ``blocked`` on the bin (code len(STATES))."""
    out: list[list[float]] = []
    s = spans[spans["state"].isin(STATES) & (spans["end"] >= t0) & (spans["start"] <= t1)]
    for row in s.itertuples(index=False):
        out.append([int(row.robot) - 1, STATES.index(row.state), _r(row.start), _r(row.end)])
    for robot, a, b in changes:
        if b >= t0 and a <= t1:
            out.append([robot, len(STATES), _r(a), _r(b)])
    return out


def _outfeed(
    parts: pd.DataFrame, plan: LinePlan, line: Any, t0: float, t1: float
) -> dict[str, Any] | None:
    """The outfeed's geometry, the containers on it during [t0, t1] and their filled slots."""
    of = plan.outfeed
    if of is None:
        return None
    cfg = line.outfeed
    lo = min(r.spec.workspace[0] for r in plan.robots) - cfg.container_length
    hi = max(r.spec.workspace[1] for r in plan.robots) + cfg.container_length
    visible = (hi - lo) / abs(of.u)
    times = np.asarray(of.times)
    first = int(np.searchsorted(times, t0 - visible, side="left"))
    last = int(np.searchsorted(times, t1, side="right"))
    fills: list[list[float]] = []
    if "container" in parts.columns:
        mine = parts[(parts["container"] >= first) & (parts["container"] < last)]
        for row in mine.itertuples(index=False):
            if math.isfinite(row.placed_at):
                fills.append([int(row.container), int(row.slot), _r(row.placed_at)])
    return {
        "u": of.u,
        "xIn": of.x_in,
        "y": of.y,
        "lo": lo,
        "hi": hi,
        "length": cfg.container_length,
        "width": cfg.container_width,
        "dx": list(of.dx),
        "dy": list(of.dy),
        "first": first,
        "times": [_r(x) for x in times[first:last]],
        "fills": fills,
    }


# -- where things are at an instant (as the page draws them) ---------------------------------
def leg_position(leg: list[float], t: float, speed: float, acc: float) -> tuple[float, float]:
    """Where a tool on ``leg`` (a data row: t0, t1, x0, y0, x1, y1, mode) is at ``t``."""
    a, b, x0, y0, x1, y1, mode = leg
    if t >= b:
        return (x1, y1)
    if t <= a:
        return (x0, y0)
    if mode == FOLLOW:
        f = (t - a) / (b - a)
        return (x0 + f * (x1 - x0), y0 + f * (y1 - y0))
    return position_along((x0, y0), (x1, y1), t - a, speed, acc)


def tools_at(data: Mapping[str, Any], t: float) -> list[tuple[float, float]]:
    """Each robot's tool position at ``t`` (the base before its first leg)."""
    out = []
    for robot, legs in zip(data["robots"], data["legs"], strict=True):
        now = [g for g in legs if g[0] <= t]
        if now:
            out.append(leg_position(now[-1], t, robot["speed"], robot["acc"]))
        elif legs:
            out.append((legs[0][2], legs[0][3]))
        else:
            out.append(tuple(robot["base"]))
    return out


def parts_at(data: Mapping[str, Any], t: float) -> dict[int, tuple[float, float]]:
    """Every shown part's position at ``t``, by part id: on the belt x = v (t - fed), from the
    grip in its robot's tool until placed (then in the bin or slot: not listed)."""
    p = data["parts"]
    v = data["belt"]["speed"]
    tools = None
    out: dict[int, tuple[float, float]] = {}
    for i, pid in enumerate(p["id"]):
        fed, picked, placed = p["fed"][i], p["picked"][i], p["placed"][i]
        if t < fed:
            continue
        if picked is None or t < picked:
            if p["fate"][i] != 0 and t >= p["left"][i]:
                continue
            out[pid] = (v * (t - fed), p["y"][i])
        elif placed is None or t < placed:
            tools = tools or tools_at(data, t)
            out[pid] = tools[p["robot"][i]]
    return out


def running_g(data: Mapping[str, Any], t: float) -> tuple[int, int]:
    """(picked, lost) by ``t`` of the parts G counts (fed after the warm-up, of a kind some
    robot picks), as the page's clock shows them."""
    p = data["parts"]
    picked, lost = data["before"]["picked"], data["before"]["lost"]
    t0 = data["t0"]
    for i in range(len(p["id"])):
        if not p["counted"][i]:
            continue
        if p["fate"][i] == 0 and p["picked"][i] is not None and t0 <= p["picked"][i] < t:
            picked += 1
        elif p["fate"][i] == 1 and t0 <= p["left"][i] < t:
            lost += 1
    return picked, lost
