"""Feature set ``student-v2``, compiled: the decision features of :mod:`.features` plus the
deciding robot's second pick, in one numba pass (a decision's vector in about a microsecond).

Everything ``student-v1`` holds, computed the same way, and per rule's pick two more values:
after taking the pick and placing it, when would the robot have placed a second part (the
soonest it could finish any part it knows of: the other candidates and the parts upstream
of the candidates, at the belt's speed, not claimed by another robot), and how many parts it
could choose from then. The one-step lookahead's futures mostly differ in how fast the
deciding robot gets its next part; these say it without simulating.

Inputs are plain arrays so that both engines (the SimPy belt's lists, the compiled engine's
arrays) hand the same numbers to the same machine code: identical features on both.
"""

from __future__ import annotations

import numpy as np

from pnp_twin.twin.fast.jit import compiled
from pnp_twin.twin.fast.mathlib import intercept_time, move_time, py_hypot

# columns of the robot table
WS_A, WS_B, BIN_X, BIN_Y, ARM, ACC, PICK, PLACE = range(8)
HORIZON = 2.0
SINCE = 4.0
PER_PICK = 9
PER_ROBOT = 4
SLOTS = 8
"""Candidates (furthest downstream first) and upstream parts (nearest first) shown one by one."""
PER_SLOT = 4
PER_UP = 3
PER_ROBOT_PLACE = 3


def robot_table(robots: list) -> np.ndarray:  # type: ignore[type-arg]
    """The robots' specs as the compiled pass reads them (one row per robot)."""
    rows = [
        (*r.workspace, *r.bin, r.arm_speed, r.acceleration, r.pick_time, r.place_time)
        for r in robots
    ]
    return np.asarray(rows, dtype=np.float64).reshape(len(robots), 8)


def size(n_rules: int, n_robots: int) -> int:
    per_robot = PER_ROBOT + PER_ROBOT_PLACE
    return n_robots + PER_PICK * n_rules + per_robot * n_robots + 3 + slots_size(n_rules)


def slots_size(n_rules: int) -> int:
    """Length of the candidate slots, the rules' picks among them and the upstream slots."""
    return PER_SLOT * SLOTS + n_rules * SLOTS + PER_UP * SLOTS


@compiled(inline=True)
def _clip(x: float, hi: float) -> float:
    if x < 0.0:
        return 0.0
    return hi if x > hi else x


@compiled()
def _robot_state(
    now: float,
    robots: np.ndarray,
    v: float,
    belt: np.ndarray,
    busy: np.ndarray,
    since: np.ndarray,
    load: np.ndarray,
) -> None:
    """Per robot: seconds until free, seconds since its last grip, and the unclaimed parts in
    its workspace. ``belt`` rows: fed, y, holder (-1: none), grip time."""
    n = robots.shape[0]
    for r in range(n):
        busy[r] = 0.0
        since[r] = SINCE
        load[r] = 0.0
    for i in range(belt.shape[1]):
        fed, y, holder, grip = belt[0, i], belt[1, i], belt[2, i], belt[3, i]
        if holder < 0.0:
            x = v * (now - fed)
            for q in range(n):
                if robots[q, WS_A] <= x <= robots[q, WS_B]:
                    load[q] += 1.0
            continue
        r = int(holder)
        if r >= n or grip == np.inf:
            continue
        x = v * (grip - fed)
        carry = py_hypot(robots[r, BIN_X] - x, robots[r, BIN_Y] - y) / robots[r, ARM]
        free = grip + robots[r, PICK] + carry + robots[r, PLACE]
        if free - now > busy[r]:
            busy[r] = free - now
        if grip <= now and now - grip < since[r]:
            since[r] = now - grip


@compiled()
def _second(
    k: int,
    back: float,
    me: np.ndarray,
    v: float,
    xs: np.ndarray,
    ys: np.ndarray,
    up_x: np.ndarray,
    up_y: np.ndarray,
    horizon: float,
) -> tuple[float, int]:
    """After taking candidate ``k`` and being back at the bin ``back`` s from now: the soonest
    the robot could have placed a second part (capped at ``horizon``), and how many it could
    reach. ``up_x``, ``up_y``: unclaimed parts upstream of the candidates (x now, y)."""
    a, b, bx, by = me[WS_A], me[WS_B], me[BIN_X], me[BIN_Y]
    arm, acc, handling = me[ARM], me[ACC], me[PICK] + me[PLACE]
    best = horizon
    count = 0
    m = xs.shape[0]
    for q in range(m + up_x.shape[0]):
        if q == k:
            continue
        x0, y = (xs[q], ys[q]) if q < m else (up_x[q - m], up_y[q - m])
        x = x0 + v * back
        if x > b:
            continue
        t = intercept_time(x - bx, y - by, v, arm, acc)
        if x + v * t < a:
            t = (a - x) / v
        gx = x + v * t
        if gx > b:
            continue
        count += 1
        done = back + t + handling + move_time(py_hypot(bx - gx, by - y), arm, acc)
        if done < best:
            best = done
    return best, count


def work_size(n_robots: int, n_candidates: int, n_on_belt: int) -> int:
    """Length of the scratch array :func:`fill` needs."""
    return 3 * n_robots + 2 * n_candidates + 2 * n_on_belt


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
    """The ``student-v2`` vector of one decision into ``out``. ``cand`` rows: the candidates'
    x, y and interception times; ``picks``: each rule's pick; ``line``: belt speed, belt
    width, the feeder's rate; ``belt``: the on-belt parts (see _robot_state); ``work``:
    scratch of :func:`work_size` (the compiled engine's functions allocate nothing). It
    leaves each robot's seconds until free in ``work[:n]`` (the continuations read them)."""
    out[:] = 0.0
    n, m, nb = robots.shape[0], cand.shape[1], belt.shape[1]
    v, width = line[0], line[1]
    xs, ys, times = cand[0], cand[1], cand[2]
    busy, since, load = work[:n], work[n : 2 * n], work[2 * n : 3 * n]
    left, slack = work[3 * n : 3 * n + m], work[3 * n + m : 3 * n + 2 * m]
    up_x, up_y = work[3 * n + 2 * m : 3 * n + 2 * m + nb], work[3 * n + 2 * m + nb :]
    _robot_state(now, robots, v, belt, busy, since, load)
    me = robots[robot]
    b, bx, by = me[WS_B], me[BIN_X], me[BIN_Y]
    handling = me[PICK] + me[PLACE]
    for q in range(m):
        left[q] = (b - xs[q]) / v
        most = 0.0
        for d in range(robot + 1, n):
            s = (robots[d, WS_B] - xs[q]) / v - busy[d]
            most = s if d == robot + 1 or s > most else most
        slack[q] = most
    ups = 0  # unclaimed parts upstream of the candidates (which reach upstream of a)
    last = xs[m - 1]
    for i in range(nb):
        x = v * (now - belt[0, i])
        if belt[2, i] < 0.0 and x < last:
            up_x[ups] = x
            up_y[ups] = belt[1, i]
            ups += 1
    out[robot] = 1.0
    j = n
    for k in picks:
        grip_x = xs[k] + v * times[k]
        back = times[k] + handling + py_hypot(bx - grip_x, by - ys[k]) / me[ARM]
        lost = 0
        gone = 0
        for q in range(m):
            if q != k and left[q] < back:
                lost += 1
                if slack[q] <= 0.0:
                    gone += 1
        second, options = _second(k, back, me, v, xs, ys, up_x[:ups], up_y[:ups], 2 * HORIZON)
        out[j] = _clip(times[k], HORIZON)
        out[j + 1] = _clip(left[k], HORIZON)
        out[j + 2] = _clip(ys[k] / width, 1.0)
        out[j + 3] = _clip(back, HORIZON)
        out[j + 4] = min(lost, 5) / 5.0
        out[j + 5] = _clip(slack[k], 2 * HORIZON) / 2.0
        out[j + 6] = min(gone, 5) / 5.0
        out[j + 7] = _clip(second, 2 * HORIZON) / 2.0
        out[j + 8] = min(options, 5) / 5.0
        j += PER_PICK
    for r in range(n):
        out[j] = _clip(busy[r], HORIZON)
        out[j + 1] = _clip(since[r], SINCE) / SINCE
        out[j + 2] = robots[r, ARM] / 4.0
        out[j + 3] = min(load[r], 10.0) / 10.0
        j += PER_ROBOT
    out[j] = v
    out[j + 1] = line[2] / 10.0
    out[j + 2] = m / 10.0
    j += 3
    _slots(out[j:], robot, now, cand, picks, robots, v, width, belt)


@compiled()
def _slots(
    out: np.ndarray,
    robot: int,
    now: float,
    cand: np.ndarray,
    picks: np.ndarray,
    robots: np.ndarray,
    v: float,
    width: float,
    belt: np.ndarray,
) -> None:
    """The candidates one by one (place along the workspace shifted by 1, across the belt,
    interception time, present), which candidate each rule picks (one-hot per rule), the
    unclaimed parts upstream of the workspace nearest first (distance to it in half metres,
    across, present), and each robot's place (workspace start less this robot's plus 2 m,
    downstream of this robot, this robot)."""
    n, m = robots.shape[0], cand.shape[1]
    a, b = robots[robot, WS_A], robots[robot, WS_B]
    for q in range(min(m, SLOTS)):
        k = PER_SLOT * q
        out[k] = _clip((cand[0, q] - a) / (b - a) + 1.0, 3.0)
        out[k + 1] = _clip(cand[1, q] / width, 1.0)
        out[k + 2] = _clip(cand[2, q], HORIZON)
        out[k + 3] = 1.0
    j = PER_SLOT * SLOTS
    for r in range(picks.shape[0]):
        if picks[r] < SLOTS:
            out[j + r * SLOTS + picks[r]] = 1.0
    j += picks.shape[0] * SLOTS
    ups = 0
    for i in range(belt.shape[1]):  # fed in order: the nearest upstream part comes first
        x = v * (now - belt[0, i])
        if ups < SLOTS and belt[2, i] < 0.0 and x < a:
            out[j + PER_UP * ups] = _clip((a - x) / 0.5, 4.0)
            out[j + PER_UP * ups + 1] = _clip(belt[1, i] / width, 1.0)
            out[j + PER_UP * ups + 2] = 1.0
            ups += 1
    j += PER_UP * SLOTS
    for r in range(n):
        out[j] = _clip(robots[r, WS_A] - a + 2.0, 4.0)
        out[j + 1] = 1.0 if r > robot else 0.0
        out[j + 2] = 1.0 if r == robot else 0.0
        j += PER_ROBOT_PLACE
