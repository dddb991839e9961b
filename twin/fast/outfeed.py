"""The place leg onto an outfeed in the compiled engine (``twin/outfeed.py`` and
``Robot._placing`` in ``twin/robot.py``, operation for operation).

After the grip the robot takes the free slot it meets soonest (:func:`_nearest_slot`),
reserves it and places; with none in reach it holds the part until the next slot enters its
place interval (:func:`_next_slot_entry`), then tries again (:func:`_place_onto`, resumed
at PC_HOLDING). ``p``, ``s``, ``rec``: the run's parameters, state and records
(:mod:`twin.fast.structs`).
"""

from __future__ import annotations

import math

from pnp_twin.twin.fast.calendar import _schedule
from pnp_twin.twin.fast.jit import compiled
from pnp_twin.twin.fast.layout import (
    ACC,
    ACTIVE,
    HOLD0,
    N_OG,
    N_ORB,
    NORMAL,
    OENTRY,
    OHI,
    OLO,
    OUT_NS,
    OUT_NT,
    OUT_ORB,
    OUT_TIMES,
    OUT_U,
    OUT_XIN,
    OUT_Y,
    PC,
    PC_HOLDING,
    PC_PLACE,
    S_HOLDING,
    SLOTX,
    SLOTY,
    TX,
    TY,
    VR,
)
from pnp_twin.twin.fast.mathlib import place_intercept
from pnp_twin.twin.fast.robot import _bisect, _span


@compiled()
def _nearest_slot(p, s, r, tx, ty, now, place):
    """Outfeed.nearest: (container, slot, interception time, x, y) of the free slot robot r
    meets soonest from (tx, ty); container -1 when none is reachable."""
    og, taken = p.og, s.taken
    u = og[OUT_U]
    ns = int(og[OUT_NS])
    orb = int(og[OUT_ORB]) + r * ns * N_ORB  # this robot's place intervals
    t0 = int(og[OUT_TIMES])
    times = og[t0 : t0 + int(og[OUT_NT])]
    v_r = p.fp[r, VR]
    acc = p.fp[r, ACC]
    last = _bisect(times, now, True, 0) - 1  # the newest container that has entered
    best_c = -1
    best_k = -1
    best_t = math.inf
    best_x = 0.0
    best_y = 0.0
    for c in range(last, -1, -1):
        gone = True
        for k in range(ns):
            lo = og[orb + k * N_ORB + OLO]
            hi = og[orb + k * N_ORB + OHI]
            x = og[OUT_XIN] + u * (now - times[c]) + og[N_OG + 2 * k]
            if (u > 0 and x <= hi) or (u < 0 and x >= lo):
                gone = False
            if taken[c, k] != 0 or lo > hi:
                continue
            y = og[OUT_Y] + og[N_OG + 2 * k + 1]
            t = place_intercept(x - tx, y - ty, u, v_r, acc)
            xi = x + u * t
            xe = xi + u * place
            if not (lo <= xi and xi <= hi and lo <= xe and xe <= hi):
                continue
            if (
                best_c < 0
                or t < best_t
                or (t == best_t and (c < best_c or (c == best_c and k < best_k)))
            ):
                best_c = c
                best_k = k
                best_t = t
                best_x = xi
                best_y = y
        if gone:
            break
    return best_c, best_k, best_t, best_x, best_y


@compiled()
def _next_slot_entry(p, r, now):
    """OutfeedPlan.next_entry: the first instant after ``now`` a slot enters robot r's
    place interval (inf: none)."""
    og = p.og
    ns = int(og[OUT_NS])
    orb = int(og[OUT_ORB]) + r * ns * N_ORB  # this robot's place intervals
    t0 = int(og[OUT_TIMES])
    n = int(og[OUT_NT])
    times = og[t0 : t0 + n]
    best = math.inf
    for k in range(ns):
        wait = og[orb + k * N_ORB + OENTRY]
        if wait == math.inf:
            continue
        c = _bisect(times, now - wait, True, 0)  # then exactly: the first entering after now
        while c > 0 and times[c - 1] + wait > now:
            c -= 1
        while c < n and times[c] + wait <= now:
            c += 1
        if c < n and times[c] + wait < best:
            best = times[c] + wait
    return best


@compiled()
def _place_onto(p, s, rec, r, part, place, now):
    """Robot._placing from the grip (or a hold's wake-up at PC_HOLDING): reserve the nearest
    free slot and place, or hold until the next slot enters the robot's place interval."""
    fs, ist = s.fs, s.ist
    rec_i, rec_f = rec.rec_i, rec.rec_f
    c, k, t, x, y = _nearest_slot(p, s, r, fs[r, TX], fs[r, TY], now, place)
    if c < 0:
        if fs[r, HOLD0] == -math.inf:
            fs[r, HOLD0] = now
            rec_f[part, 4] = now
        wake = _next_slot_entry(p, r, now)
        if wake == math.inf:  # no slot will ever come: hold to the end of the run
            ist[r, ACTIVE] = 0
            ist[r, PC] = PC_HOLDING
        else:
            _schedule(s, r, now + (wake - now), NORMAL, PC_HOLDING)
        return
    held = 0.0
    if fs[r, HOLD0] > -math.inf:
        _span(s, rec, r, S_HOLDING, fs[r, HOLD0], now)
        held = now - fs[r, HOLD0]
    s.taken[c, k] = 1
    done = now + t + place
    rec_f[part, 2] = done
    rec_i[part, 2] = c
    rec_i[part, 3] = k
    rec_f[part, 5] = held
    fs[r, SLOTX] = x + p.og[OUT_U] * place
    fs[r, SLOTY] = y
    _schedule(s, r, now + (done - now), NORMAL, PC_PLACE)
