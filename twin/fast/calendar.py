"""The kernel's event calendar: each robot's one live wake-up, and which comes first.

SimPy's event queue orders events by (time, priority, creation number). Every robot has at
most one live wake-up (a timeout, a release of its decision hold or a t_any interruption),
kept in its row of the state arrays (:func:`_schedule`; ``s`` is the run's
:class:`~twin.fast.structs.State`); a loser tree over the robots
(:func:`_calendar`) gives the first in SimPy's order, and settles again in log2(N) matches
when that robot's wake-up changes (:func:`_replay`), instead of a scan of every robot.
"""

from __future__ import annotations

import math

from pnp_twin.twin.fast.jit import compiled
from pnp_twin.twin.fast.layout import (
    ACTIVE,
    CAL,
    CALW,
    PC,
    SEQ,
    WAKE,
    WPRIO,
    WSEQ,
)


@compiled(inline=True)
def _schedule(s, r, at, prio, pc):
    fs, ist, gs = s.fs, s.ist, s.gs
    fs[r, WAKE] = at
    ist[r, WPRIO] = prio
    ist[r, WSEQ] = gs[SEQ]
    gs[SEQ] += 1
    ist[r, ACTIVE] = 1
    ist[r, PC] = pc


@compiled(inline=True)
def _before(ist, i, wi, j, wj):
    """Robot i's wake-up (at wi) comes before robot j's (at wj), in SimPy's (time,
    priority, sequence) order; no robot (-1) comes after every robot."""
    if i < 0:
        return False
    if j < 0:
        return True
    return wi < wj or (
        wi == wj
        and (
            ist[i, WPRIO] < ist[j, WPRIO]
            or (ist[i, WPRIO] == ist[j, WPRIO] and ist[i, WSEQ] < ist[j, WSEQ])
        )
    )


@compiled(inline=True)
def _leaf(fs, ist, i):
    """Leaf i of the calendar: robot i and its wake-up time when it has one scheduled,
    else -1 (none)."""
    if i < ist.shape[0] and ist[i, ACTIVE]:
        return i, fs[i, WAKE]
    return -1, math.inf


@compiled(inline=True)
def _child(fs, ist, m, c):
    """Node c's robot and time: a leaf (c >= m) or a stored node."""
    if c >= m:
        return _leaf(fs, ist, c - m)
    return int(fs[c >> 1, CAL + (c & 1)]), fs[c >> 1, CALW + (c & 1)]


@compiled(inline=True)
def _store(fs, k, robot, wake):
    fs[k >> 1, CAL + (k & 1)] = robot
    fs[k >> 1, CALW + (k & 1)] = wake


@compiled()
def _calendar(s):
    """The event calendar afresh: a loser tree over the robots. Inner node k (1 <= k < m)
    holds the loser of the match between the winners of its two subtrees (the robot and its
    wake-up time, side by side in row k // 2 of ``fs``: columns CAL + k % 2 and
    CALW + k % 2); node 0 (``fs[0, CAL]``) the overall winner: the robot whose wake-up
    comes first, -1 when none. When the winner's wake-up changes, :func:`_replay` settles
    the calendar in log2(N) matches, one row each, instead of a scan of every robot.
    Returns the width m (the leaves' count, a power of two >= the robots)."""
    fs, ist = s.fs, s.ist
    m = 1
    while m < ist.shape[0]:
        m *= 2
    if m == 1:
        r, w = _leaf(fs, ist, 0)
        _store(fs, 0, r, w)
        return m
    for k in range(m - 1, 0, -1):  # each node's winner, bottom up
        a, wa = _child(fs, ist, m, 2 * k)
        b, wb = _child(fs, ist, m, 2 * k + 1)
        if _before(ist, b, wb, a, wa):
            _store(fs, k, b, wb)
        else:
            _store(fs, k, a, wa)
    r, w = _child(fs, ist, m, 1)
    _store(fs, 0, r, w)  # node 1's winner wins
    for k in range(1, m):  # top down, each node's winner becomes its loser
        a, wa = _child(fs, ist, m, 2 * k)
        b, wb = _child(fs, ist, m, 2 * k + 1)
        if int(fs[k >> 1, CAL + (k & 1)]) == a:
            _store(fs, k, b, wb)
        else:
            _store(fs, k, a, wa)
    return m


@compiled(inline=True)
def _replay(s, m, r):
    """The wake-up of robot r, the calendar's winner, changed (scheduled again, or not)."""
    fs, ist = s.fs, s.ist
    w, ww = _leaf(fs, ist, r)
    k = (m + r) >> 1
    while k >= 1:
        lo = int(fs[k >> 1, CAL + (k & 1)])
        lw = fs[k >> 1, CALW + (k & 1)]
        if _before(ist, lo, lw, w, ww):
            _store(fs, k, w, ww)
            w, ww = lo, lw
        k >>= 1
    _store(fs, 0, w, ww)


@compiled(inline=True)
def _first(s):
    """The robot whose wake-up comes first, -1 when none."""
    return int(s.fs[0, CAL])
