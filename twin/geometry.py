"""Line geometry: the workspace and bin layout, tool move times, and the interception of a
part on the moving belt. The only copy of these formulas: the twin, the policies and the
reports all call them.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import TypeVar

import numpy as np

Times = TypeVar("Times", float, np.ndarray)


def workspaces(
    count: int,
    first_start: float,
    length: float,
    gap: float,
    explicit: Sequence[Sequence[float]] | None = None,
) -> list[tuple[float, float]]:
    """Workspace bounds [a_i, b_i] in m, upstream first: ``explicit`` ones, or ``count``
    back to back from ``first_start``, each ``length`` long, ``gap`` apart."""
    if explicit is not None:
        return [(float(a), float(b)) for a, b in explicit]
    a = first_start
    out = []
    for _ in range(count):
        out.append((a, a + length))
        a += length + gap
    return out


def bin_position(
    workspace: tuple[float, float],
    belt_width: float,
    offset: Sequence[float],
    side: str = "upper",
) -> tuple[float, float]:
    """A robot's place target: ``offset`` (dx, dy) from (workspace centre, upper belt edge),
    mirrored to the lower edge (y = -dy) for a robot on the lower side; an "over" robot's
    bin is at the offset as given (from the upper edge)."""
    a, b = workspace
    dx, dy = offset
    if side == "lower":
        return ((a + b) / 2.0 + dx, -dy)
    return ((a + b) / 2.0 + dx, belt_width + dy)


def mount_position(
    workspace: tuple[float, float], belt_width: float, side: str, offset: float
) -> tuple[float, float]:
    """Where a robot's base stands (its reach is measured from here): at the workspace
    centre, ``offset`` beyond the belt edge of its side, or above the belt's centre line."""
    xc = (workspace[0] + workspace[1]) / 2.0
    if side == "over":
        return (xc, belt_width / 2.0)
    if side == "lower":
        return (xc, -offset)
    return (xc, belt_width + offset)


def exit_time(fed_at: Times, end: float, speed: float) -> Times:
    """When a part fed at ``fed_at`` passes x = ``end`` (the end of the last workspace);
    elementwise for an array of feeding times."""
    return fed_at + end / speed


def intercept_quad(arm_speed: float, belt_speed: float) -> float:
    """v_r^2 - v_b^2, the leading coefficient of the interception quadratic."""
    return arm_speed**2 - belt_speed**2


def intercept_now(dx: float, dy: float, belt_speed: float, quad: float) -> float:
    """Closed-form interception time without an acceleration limit (``quad`` from
    :func:`intercept_quad`): the root T >= 0 of (dx + v_b T)^2 + dy^2 = (v_r T)^2."""
    v = belt_speed
    return (dx * v + math.sqrt(dx * dx * (v * v) + quad * (dx * dx + dy * dy))) / quad


def move_time(distance: float, speed: float, acceleration: float = 0.0) -> float:
    """Time of a straight move from rest to rest; trapezoidal when ``acceleration`` > 0."""
    if acceleration <= 0.0:
        return distance / speed
    ramp = speed * speed / acceleration  # distance spent accelerating plus braking
    if distance >= ramp:
        return distance / speed + speed / acceleration
    return 2.0 * math.sqrt(distance / acceleration)


def intercept_time(
    dx: float, dy: float, belt_speed: float, arm_speed: float, acceleration: float = 0.0
) -> float:
    """Earliest T >= 0 at which a tool reaches a part now at offset (dx, dy) from it.

    The part moves at ``belt_speed`` along +x. With no acceleration limit T solves
    (dx + v_b T)^2 + dy^2 = (v_r T)^2 in closed form (the paper's relative-velocity
    construction); with one it is the smallest T where the trapezoidal move time to the
    part's position at T is at most T, found by stepping and bisection.
    """
    a = arm_speed * arm_speed - belt_speed * belt_speed
    t = (
        dx * belt_speed + math.sqrt(dx * dx * belt_speed * belt_speed + a * (dx * dx + dy * dy))
    ) / a
    if acceleration <= 0.0:
        return t

    def late(tt: float) -> float:
        x = dx + belt_speed * tt
        return move_time(math.hypot(x, dy), arm_speed, acceleration) - tt

    lo, step = t, max(arm_speed / acceleration, 1e-3) / 8.0
    hi = lo + step
    # where the part passes nearest the tool the move is shortest: if the tool can be there
    # in time, the first meeting is before it (``late`` falls until then), else it is later
    # (stepping on from the first instant the tool could be there without the limit)
    closest = -dx / belt_speed if belt_speed != 0.0 else -math.inf
    if closest > lo and late(closest) <= 0.0:
        hi = closest
    else:
        while late(hi) > 0.0:
            lo, hi = hi, hi + step
    for _ in range(50):
        mid = 0.5 * (lo + hi)
        if late(mid) > 0.0:
            lo = mid
        else:
            hi = mid
    return hi


def place_intercept(
    dx: float, dy: float, velocity: float, arm_speed: float, acceleration: float = 0.0
) -> float:
    """Earliest T >= 0 at which a tool reaches a slot of the outfeed now at offset (dx, dy)
    from it: the pick's interception (:func:`intercept_time`) with the outfeed's signed
    ``velocity`` (negative for counter-flow) in place of the belt speed; the closed form
    (dx + u T)^2 + dy^2 = (v_r T)^2 holds for either sign of u."""
    return intercept_time(dx, dy, velocity, arm_speed, acceleration)


def position_along(
    start: tuple[float, float],
    end: tuple[float, float],
    elapsed: float,
    speed: float,
    acceleration: float = 0.0,
) -> tuple[float, float]:
    """Where a tool moving from ``start`` to ``end`` is after ``elapsed`` seconds."""
    dist = math.hypot(end[0] - start[0], end[1] - start[1])
    if dist <= 0.0:
        return start
    total = move_time(dist, speed, acceleration)
    if elapsed >= total:
        return end
    if acceleration <= 0.0:
        done = speed * elapsed
    else:
        t_acc = min(speed / acceleration, total / 2.0)
        v_top = acceleration * t_acc
        if elapsed <= t_acc:
            done = 0.5 * acceleration * elapsed * elapsed
        elif elapsed <= total - t_acc:
            done = 0.5 * v_top * t_acc + v_top * (elapsed - t_acc)
        else:
            left = total - elapsed
            done = dist - 0.5 * acceleration * left * left
    f = min(done / dist, 1.0)
    return (start[0] + f * (end[0] - start[0]), start[1] + f * (end[1] - start[1]))
