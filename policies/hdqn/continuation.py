"""Feature sets ``student-v3`` and ``-v4``'s tails, compiled: per rule's pick, the line played
on over the parts already on the belt, every robot following SPT.

The lookahead controller values a pick by playing the line on under sampled futures. These
continuations do it cheaply, in one deterministic future: only the parts already on the belt
(none arrive). A robot picks when it is free: back at its bin, it takes the unclaimed part
with the shortest full cycle among those it can intercept in its workspace, or waits until
the nearest part upstream comes within reach.

- ``student-v3`` (the short continuation): a second of it, counting the grips in that second.
- ``student-v4`` adds the long one, which counts as the teacher counts: the teacher scores a
  pick by the parts fed before ``t + H`` that are ever gripped, so it plays each future on
  until those parts have left the line. The long continuation plays on until every part on
  the belt has passed the last workspace and counts the ones gripped.

Per rule's pick, each gives: the parts gripped (all robots), by the robots downstream of the
deciding one, by the deciding robot after the pick, and how many fewer than the best pick's.
(A continuation with typical arrivals, at the nominal rate, told the teacher's choices apart
no better on held-out labels than the short one. On one line's held-out labels, four futures
with sampled arrivals cut the network's regret by a further eighth on top of the long one, at
ten times its cost; neither is computed.)
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
)
from pnp_twin.twin.fast.jit import compiled
from pnp_twin.twin.fast.mathlib import intercept_time, move_time, py_hypot

PER_ROLL = 4
"""Values per rule's pick."""
HORIZON = 1.0
"""Seconds the short continuation runs (the teacher's horizon)."""
STEPS = 96
"""At most this many picks or waits per short continuation."""
LONG_STEPS = 512
"""At most this many picks or waits per long continuation."""
SCALE_SHORT = (20.0, 10.0, 5.0, 3.0)
"""The short continuation's values (grips, downstream, own, shortfall) are clipped to these
and divided by them."""
SCALE_LONG = (40.0, 30.0, 10.0, 3.0)
"""The long continuation's values are clipped to these and divided by them."""
WAIT_MIN = 0.01
"""A robot with nothing in reach waits at least this long before looking again."""


def size(n_rules: int, long: bool = False) -> int:
    """Values of the short continuation's tail (with ``long``, and of the long one's)."""
    return PER_ROLL * n_rules * (2 if long else 1)


def work_size(n_robots: int, n_on_belt: int, n_rules: int) -> int:
    """Length of the scratch array :func:`fill` needs."""
    return n_robots + 2 * n_rules + 3 * n_on_belt


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
    stop: float,
    until: float,
    steps: int,
) -> tuple[int, int, int]:
    """``robot`` takes part ``k``, free again ``first`` s from now; then every robot picks
    by SPT from the untaken parts, starting picks for ``stop`` s (at most ``steps`` picks
    or waits). ``px`` (x now), ``py``: the parts in the order they were fed (furthest
    downstream first); ``taken`` and ``free`` (seconds until each robot is free) are
    scratch the caller filled and this changes. Returns the grips made before ``until``
    s: all (``k``'s too), by the robots downstream of ``robot``, by ``robot`` after
    ``k``."""
    n, m = robots.shape[0], px.shape[0]
    if k >= 0:
        taken[k] = 1.0
    free[robot] = first
    total, down, mine = 1, 0, 0
    for _ in range(steps):
        r = -1
        for q in range(n):
            if free[q] < stop and (r < 0 or free[q] < free[r]):
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
        if t + grip < until:
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
    busy: np.ndarray,
    work: np.ndarray,
    long: bool,
) -> None:
    """The short continuation's values into ``out`` (rule by rule), then with ``long`` the
    long one's (:func:`size` values in all). Arguments as :func:`features_compiled.fill`'s;
    ``busy``: each robot's seconds until free, as that pass estimated them (it leaves them
    in its scratch); ``work``: :func:`work_size` scratch, apart from ``busy``."""
    n, nr, m = robots.shape[0], picks.shape[0], belt.shape[1]
    free, totals = work[:n], work[n : n + 2 * nr]
    o = n + 2 * nr
    px, held, taken = work[o : o + m], work[o + m : o + 2 * m], work[o + 2 * m : o + 3 * m]
    v = line[0]
    for i in range(m):
        px[i] = v * (now - belt[0, i])
        held[i] = 1.0 if belt[2, i] >= 0.0 else 0.0
    me = robots[robot]
    last = 0.0
    for q in range(n):
        last = max(last, robots[q, WS_B])
    for j in range(nr):
        k = picks[j]
        same = -1
        for i in range(j):
            if picks[i] == k and same < 0:
                same = i
        if same >= 0:  # the same part: the same values
            totals[j] = totals[same]
            totals[nr + j] = totals[nr + same]
            for c in range(PER_ROLL - 1):
                out[PER_ROLL * j + c] = out[PER_ROLL * same + c]
                if long:
                    out[PER_ROLL * (nr + j) + c] = out[PER_ROLL * (nr + same) + c]
            continue
        xk, yk, tk = cand[0, k], cand[1, k], cand[2, k]
        part = -1
        for i in range(m):
            if part < 0 and held[i] == 0.0 and abs(px[i] - xk) < 1e-9 and belt[1, i] == yk:
                part = i
        gx = xk + v * tk
        first = tk + me[PICK] + me[PLACE]
        first += move_time(py_hypot(me[BIN_X] - gx, me[BIN_Y] - yk), me[ARM], me[ACC])
        for s in range(2 if long else 1):
            for i in range(m):
                taken[i] = held[i]
            for q in range(n):
                free[q] = busy[q]
            if s == 0:
                stop, until, steps, scale = HORIZON, HORIZON, STEPS, SCALE_SHORT
            else:
                stop, until, steps, scale = last / v, np.inf, LONG_STEPS, SCALE_LONG
            got = _continue(
                robot, part, first, robots, v, px, belt[1], taken, free, stop, until, steps
            )
            o = PER_ROLL * (s * nr + j)
            totals[s * nr + j] = got[0]
            for c in range(PER_ROLL - 1):
                out[o + c] = min(float(got[c]), scale[c]) / scale[c]
    for s in range(2 if long else 1):
        most = 0.0
        for j in range(nr):
            most = max(most, totals[s * nr + j])
        top = SCALE_SHORT[3] if s == 0 else SCALE_LONG[3]
        for j in range(nr):
            out[PER_ROLL * (s * nr + j) + 3] = min(most - totals[s * nr + j], top) / top
