"""Tool moves: straight-line move times and the interception of a part on the moving belt."""

from __future__ import annotations

import math


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
    while late(hi) > 0.0:
        lo, hi = hi, hi + step
    for _ in range(50):
        mid = 0.5 * (lo + hi)
        if late(mid) > 0.0:
            lo = mid
        else:
            hi = mid
    return hi


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
