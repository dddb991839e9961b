"""Feature set ``student-v3``'s tail, compiled: per rule's pick, the line played on for a
second over the parts already on the belt, every robot following SPT.

The lookahead controller values a pick by playing the line on under sampled futures. This
continuation does it cheaply, in one deterministic future: only the parts already on the belt
(none arrive). Per rule's pick: the parts gripped within the horizon (all robots), by the
robots downstream of the deciding one, by the deciding robot after the pick, and how many
fewer than the best pick's. A robot picks when it is free: back at its bin, it takes the
unclaimed part with the shortest full cycle among those it can intercept in its workspace,
or waits until the nearest part upstream comes within reach. (A second continuation with
typical arrivals, at the nominal rate, told the teacher's choices apart no better on held-out
labels, so it is not computed.)
"""

from __future__ import annotations

import numpy as np

from pnp_twin.policies.hdqn.features_compiled import (
    ACC,
    ARM,
    BIN_X,
    BIN_Y,
    PICK,
    PLACE,
    WS_A,
    WS_B,
    _robot_state,
)
from pnp_twin.twin.fast.jit import compiled
from pnp_twin.twin.fast.mathlib import intercept_time, move_time, py_hypot

PER_ROLL = 4
"""Values per rule's pick."""
HORIZON = 1.0
"""Seconds the continuation runs (the teacher's horizon)."""
STEPS = 96
"""At most this many picks or waits per continuation."""
WAIT_MIN = 0.01
"""A robot with nothing in reach waits at least this long before looking again."""


def size(n_rules: int) -> int:
    return PER_ROLL * n_rules


def work_size(n_robots: int, n_on_belt: int, n_rules: int) -> int:
    """Length of the scratch array :func:`fill` needs."""
    return 4 * n_robots + n_rules + 3 * n_on_belt


@compiled()
def _continue(
    robot: int,
    k: int,
    first: float,
    robots: np.ndarray,
    v: float,
    px: np.ndarray,
    py: np.ndarray,
    taken: np.ndarray,
    free: np.ndarray,
) -> tuple[int, int, int]:
    """``robot`` takes part ``k``, free again ``first`` s from now; then every robot picks
    by SPT from the untaken parts for :data:`HORIZON` s. ``px`` (x now), ``py``: the parts
    in the order they were fed (furthest downstream first); ``taken`` and ``free`` (seconds
    until each robot is free) are scratch the caller filled and this changes. Returns the
    grips in that time: all, by the robots downstream of ``robot``, by ``robot`` after
    ``k``."""
    n, m = robots.shape[0], px.shape[0]
    if k >= 0:
        taken[k] = 1.0
    free[robot] = first
    total, down, mine = 1, 0, 0
    for _ in range(STEPS):
        r = -1
        for q in range(n):
            if free[q] < HORIZON and (r < 0 or free[q] < free[r]):
                r = q
        if r < 0:
            break
        t = free[r]
        a, b, bx, by = robots[r, WS_A], robots[r, WS_B], robots[r, BIN_X], robots[r, BIN_Y]
        arm, acc = robots[r, ARM], robots[r, ACC]
        best, pick, grip, wait = np.inf, -1, 0.0, np.inf
        for i in range(m):
            x = px[i] + v * t
            if taken[i] != 0.0 or x > b:
                continue
            ti = intercept_time(x - bx, py[i] - by, v, arm, acc)
            xi = x + v * ti
            if xi > b:
                continue
            if xi < a:  # not in reach yet: about when its interception point gets to a;
                wait = (a - xi) / v  # the parts after it (fed later) are further upstream
                break
            cycle = ti + robots[r, PICK] + robots[r, PLACE]
            cycle += move_time(py_hypot(bx - xi, by - py[i]), arm, acc)
            if cycle < best:
                best, pick, grip = cycle, i, ti
        if pick < 0:
            free[r] = t + max(wait, WAIT_MIN) if wait < np.inf else np.inf
            continue
        taken[pick] = 1.0
        free[r] = t + best
        if t + grip < HORIZON:
            total += 1
            down += r > robot
            mine += r == robot
    return total, down, mine


@compiled()
def fill(
    out: np.ndarray,
    robot: int,
    now: float,
    cand: np.ndarray,
    picks: np.ndarray,
    robots: np.ndarray,
    line: np.ndarray,
    belt: np.ndarray,
    work: np.ndarray,
) -> None:
    """``student-v3``'s tail into ``out`` (:func:`size` values, rule by rule). Arguments as
    :func:`features_compiled.fill`'s; ``work``: :func:`work_size` scratch."""
    n, nr, m = robots.shape[0], picks.shape[0], belt.shape[1]
    busy, since, load = work[:n], work[n : 2 * n], work[2 * n : 3 * n]
    free, totals = work[3 * n : 4 * n], work[4 * n : 4 * n + nr]
    o = 4 * n + nr
    px, held, taken = work[o : o + m], work[o + m : o + 2 * m], work[o + 2 * m : o + 3 * m]
    v = line[0]
    _robot_state(now, robots, v, belt, busy, since, load)
    for i in range(m):
        px[i] = v * (now - belt[0, i])
        held[i] = 1.0 if belt[2, i] >= 0.0 else 0.0
    me = robots[robot]
    most = 0.0
    for j in range(nr):
        k = picks[j]
        o = PER_ROLL * j
        same = -1
        for i in range(j):
            if picks[i] == k and same < 0:
                same = i
        if same >= 0:
            for c in range(PER_ROLL - 1):
                out[o + c] = out[PER_ROLL * same + c]
            totals[j] = totals[same]
            continue
        xk, yk, tk = cand[0, k], cand[1, k], cand[2, k]
        part = -1
        for i in range(m):
            taken[i] = held[i]
            if part < 0 and held[i] == 0.0 and abs(px[i] - xk) < 1e-9 and belt[1, i] == yk:
                part = i
        for q in range(n):
            free[q] = busy[q]
        gx = xk + v * tk
        first = tk + me[PICK] + me[PLACE]
        first += move_time(py_hypot(me[BIN_X] - gx, me[BIN_Y] - yk), me[ARM], me[ACC])
        total, down, mine = _continue(robot, part, first, robots, v, px, belt[1], taken, free)
        totals[j] = total
        most = max(most, float(total))
        out[o] = min(total, 20) / 20.0
        out[o + 1] = min(down, 10) / 10.0
        out[o + 2] = min(mine, 5) / 5.0
    for j in range(nr):
        out[PER_ROLL * j + 3] = min(most - totals[j], 3.0) / 3.0
