"""The range of lines a student was trained on, and one warning when a line lies far outside.

A student trained across lines (``train_args.lines`` in its ``meta.json``) has the belt
speed, the feeder's rate, each robot's arm speed and the robot count among its inputs, so
it is not tied to one scenario; but far outside what it saw it may not hold up. Its range
is each of those quantities' least and greatest value over its training lines (recorded in
``train_args.ranges`` by newer trainings; worked out from the lines' scenarios for older
ones). A line whose value lies more than :data:`MARGIN` outside a range gets one warning
line per process and range.
"""

from __future__ import annotations

import logging
from typing import Any

from pnp_twin.twin.decision import RobotSpec
from pnp_twin.twin.loader import load_scenario, parse_sets
from pnp_twin.twin.scenario import Scenario

log = logging.getLogger(__name__)
MARGIN = 0.1
"""A value more than 10 % below a range's least or above its greatest is far outside."""
_WARNED: set[tuple[Any, ...]] = set()
Ranges = dict[str, list[float]]


def _arms(scenario: Scenario) -> list[float]:
    robots = scenario.robots
    return [float(robots.param(i + 1, "arm_speed")) for i in range(robots.count)]


def ranges_of(lines: list[Scenario]) -> Ranges:
    """Each quantity's [least, greatest] over the training lines."""
    out: Ranges = {}
    for line in lines:
        arms = _arms(line)
        values = {
            "robots": [float(line.robots.count)],
            "arm_speed": arms,
            "belt_speed": [float(line.belt.speed)],
            "feeder_rate": [float(line.feeder.rate)],
        }
        for key, got in values.items():
            lo, hi = out.get(key, [min(got), max(got)])
            out[key] = [min(lo, *got), max(hi, *got)]
    return out


def training_ranges(meta: dict[str, Any]) -> Ranges | None:
    """A cross-line student's ranges (None: trained on one line, or lines unknown)."""
    args = meta.get("train_args", {})
    if isinstance(args.get("ranges"), dict):
        return {k: [float(v[0]), float(v[1])] for k, v in args["ranges"].items()}
    labels = args.get("lines", [])
    if len(labels) < 2:
        return None
    lines = []
    for label in labels:
        name, *sets = [p.strip() for p in str(label).split(" --set ")]
        try:
            lines.append(load_scenario(name, parse_sets(sets) or None))
        except Exception:  # a line of another version's scenarios: no range from it
            continue
    return ranges_of(lines) if lines else None


def warn_outside(
    ranges: Ranges, scenario: Scenario, robots: list[RobotSpec], where: str
) -> list[str]:
    """Log one warning (once per process) naming what lies far outside ``ranges``; returns
    the quantities outside."""
    now = {
        "robots": [float(len(robots))],
        "arm_speed": [float(r.arm_speed) for r in robots],
        "belt_speed": [float(scenario.belt.speed)],
        "feeder_rate": [float(scenario.feeder.rate)],
    }
    diffs = []
    for key, (lo, hi) in ranges.items():
        for value in now.get(key, []):
            if value < lo * (1 - MARGIN) or value > hi * (1 + MARGIN):
                diffs.append(f"{key} {value:g} (trained {lo:g} to {hi:g})")
                break
    seen = (where, tuple(diffs))
    if diffs and seen not in _WARNED:
        _WARNED.add(seen)
        log.warning(
            "warning: %s was trained on other lines; this one lies far outside: %s",
            where,
            ", ".join(diffs),
        )
    return diffs
