"""The compiled event loop: the SimPy twin's line as a state machine over arrays.

Each robot is one slot of arrays. The event calendar (:mod:`twin.fast.calendar`) gives the
robot whose wake-up comes first in SimPy's order (time, priority, creation number), and the
loop resumes it at its program counter: the cycle of ``twin/robot.py`` written as a state
machine, its steps in :mod:`twin.fast.robot`, the gateway's epochs in
:mod:`twin.fast.gateway`. Sequence numbers are handed out in the order the twin creates its
events, so equal-time events resolve the same way; the arithmetic is written operation for
operation as in the twin (see :mod:`twin.fast.mathlib`).

State lives in plain arrays, grouped in five structures (:mod:`twin.fast.structs`: ``p``
parameters, ``s`` state, ``rec`` records, ``st`` streams, ``sc`` scratch; column names in
:mod:`twin.fast.layout`), so a run can be copied at any point and continued.
"""

from __future__ import annotations

import math

from pnp_twin.twin.fast.calendar import _calendar, _first, _replay, _schedule
from pnp_twin.twin.fast.gateway import _down, _free, release
from pnp_twin.twin.fast.jit import compiled
from pnp_twin.twin.fast.layout import (
    ACC,
    ACTIVE,
    BINCOUNT,
    BINREADY,
    BOXES,
    BX,
    BY,
    CAPACITY,
    CHANGE,
    CLAIMED,
    DOWN,
    DOWN0,
    DROBOT,
    EXP_MARGIN,
    EXPIDX,
    EXPONENTIAL,
    FAILMODE,
    HOLD,
    HOLD0,
    KPLACE,
    MTBF,
    MTTR,
    N_FS,
    N_IS,
    NEXTFAIL,
    NORMAL,
    NOW,
    NPENDING,
    NSPANS,
    OUT_ON,
    PART,
    PC,
    PC_APPROACH,
    PC_DOWN,
    PC_HELD,
    PC_HOLDING,
    PC_INTERRUPT,
    PC_NOOP,
    PC_PLACE,
    PC_START,
    RELEASES,
    ROOM_EXPS,
    ROOM_SIRO,
    ROOM_SPANS,
    ROOMFOR,
    RULE,
    RULENOW,
    S_BLOCKED,
    S_DOWN,
    S_HOLDING,
    S_INTERRUPTED,
    S_NOOP,
    S_WAIT,
    SCHEME,
    SEQ,
    SIRO,
    SIRO_MARGIN,
    SIROIDX,
    SLOTX,
    SLOTY,
    SPAN_MARGIN,
    ST_EPOCH,
    ST_ROOM,
    STATUS,
    T0,
    T_CONTINUE,
    TAPP,
    TOOLX,
    TOOLY,
    TX,
    TY,
    VR,
    WAIT0,
    WAKE,
    WSEQ,
    V,
)
from pnp_twin.twin.fast.mathlib import move_time, position_along, py_hypot
from pnp_twin.twin.fast.outfeed import _place_onto
from pnp_twin.twin.fast.robot import (
    FREE,
    _decide,
    _draw,
    _span,
    choose_external,
    decline_external,
    start_robots,
)

__all__ = [
    "choose_external", "close_open_spans", "decline_external", "release", "run_events",
    "start_robots",
]  # fmt: skip


@compiled(inline=True)
def _short_of_room(p, s, rec, st, r):
    """Before robot r's event: would a buffer or pre-drawn stream it may use run out? Then
    stop with ST_ROOM (the state untouched), so the caller can grow it and carry on."""
    ip, gs, sp_i = p.ip, s.gs, rec.sp_i
    room = -1
    if sp_i.shape[0] > 0 and gs[NSPANS] + SPAN_MARGIN > sp_i.shape[0]:
        room = ROOM_SPANS
    elif ip[r, RULE] == SIRO and gs[SIROIDX] + SIRO_MARGIN > st.siro.shape[0]:
        room = ROOM_SIRO
    elif ip[r, FAILMODE] == EXPONENTIAL and s.ist[r, EXPIDX] + EXP_MARGIN > st.exps.shape[1]:
        room = ROOM_EXPS
    if room < 0:
        return False
    gs[STATUS] = ST_ROOM
    gs[ROOMFOR] = room
    gs[DROBOT] = r
    return True


@compiled()
def run_events(p, s, rec, st, sc, stop_at):
    """Process events with time < stop_at; returns the status: 0 (reached stop_at),
    ST_CHOOSE, ST_EPOCH, ST_ROOM (call again once grown) or, should an event still run out
    of room, ST_SPANS / ST_SIRO / ST_EXPS."""
    fp, gp, gi = p.fp, p.gp, p.gi
    fs, ist, gs, gf = s.fs, s.ist, s.gs, s.gf
    rec_i, rec_f = rec.rec_i, rec.rec_f
    v = gp[V]
    scheme = gi[SCHEME]
    capacity = gi[CAPACITY]
    waits = scheme != T_CONTINUE or gi[HOLD]  # a free robot reports to the gateway
    outfeed = p.og[OUT_ON] > 0.0  # robots place onto an outfeed, not into their bins
    m = _calendar(s)  # the callers may have scheduled robots since the last call
    while gs[STATUS] == 0:
        r = _first(s)  # the robot whose wake-up comes first (-1: none)
        if gs[NPENDING] > 0 and (r < 0 or fs[r, WAKE] > gf[NOW]):
            gs[STATUS] = ST_EPOCH  # the epoch's instant is over: the caller answers it
            break
        if r < 0 or fs[r, WAKE] >= stop_at:
            break
        if _short_of_room(p, s, rec, st, r):
            break  # ST_ROOM: the caller grows the buffer or stream and calls again
        now = fs[r, WAKE]
        gf[NOW] = now
        ist[r, ACTIVE] = 0
        seq = gs[SEQ]
        pc = ist[r, PC]
        top = False  # go to the top of the loop (failure check)
        decide = False  # go straight to the candidates
        if pc == PC_START:
            top = True
        elif pc == PC_NOOP:
            _span(s, rec, r, S_NOOP, fs[r, T0], now)
            top = True
        elif pc == PC_HELD:
            _span(s, rec, r, S_WAIT, fs[r, WAIT0], now)
            decide = True
        elif pc == PC_APPROACH:  # gripped: move to the bin and place
            part = ist[r, PART]
            ist[r, CLAIMED] = -1
            t0 = fs[r, T0]
            rec_i[part, 0] = r
            rec_i[part, 1] = ist[r, RULENOW]
            rec_f[part, 0] = t0
            rec_f[part, 1] = t0 + fs[r, TAPP]
            if outfeed:  # the place leg onto the outfeed (Robot._placing)
                fs[r, TOOLX] = fs[r, TX]
                fs[r, TOOLY] = fs[r, TY]
                fs[r, HOLD0] = -math.inf
                _place_onto(p, s, rec, r, part, p.kp[r, st.kind[part], KPLACE], now)
            else:
                v_r = fp[r, VR]
                acc = fp[r, ACC]
                dist = py_hypot(fp[r, BX] - fs[r, TX], fp[r, BY] - fs[r, TY])
                if acc <= 0.0:
                    arrive = now + dist / v_r
                else:
                    arrive = now + move_time(dist, v_r, acc)
                kind = st.kind[part]  # its chute: kind 0's columns, then one more per kind
                ready = BINREADY if kind == 0 else N_FS + kind - 1
                count = BINCOUNT if kind == 0 else N_IS + kind - 1
                start = arrive
                if fs[r, ready] > arrive:
                    start = fs[r, ready]
                done = start + p.kp[r, kind, KPLACE]
                ist[r, count] += 1
                if capacity and ist[r, count] >= capacity:
                    ist[r, count] = 0
                    ist[r, BOXES] += 1
                    fs[r, ready] = done + gp[CHANGE]
                blocked = start - arrive
                rec_f[part, 2] = done
                if blocked > 0.0:
                    rec_f[part, 3] = blocked
                    _span(s, rec, r, S_BLOCKED, arrive, arrive + blocked)
                _schedule(s, r, now + (done - now), NORMAL, PC_PLACE)
        elif pc == PC_PLACE:
            if outfeed:  # the tool moved with the slot while it released the part
                fs[r, TOOLX] = fs[r, SLOTX]
                fs[r, TOOLY] = fs[r, SLOTY]
            else:
                fs[r, TOOLX] = fp[r, BX]
                fs[r, TOOLY] = fp[r, BY]
            top = True
        elif pc == PC_HOLDING:  # a slot entered the robot's place interval: try again
            part = ist[r, PART]
            _place_onto(p, s, rec, r, part, p.kp[r, st.kind[part], KPLACE], now)
        elif pc == PC_INTERRUPT:
            part = ist[r, PART]
            s.holder[part] = FREE
            gs[RELEASES] += 1
            s.left_at[part] = math.inf
            ist[r, CLAIMED] = -1
            t0 = fs[r, T0]
            _span(s, rec, r, S_INTERRUPTED, t0, now)
            x, y = position_along(
                fs[r, TOOLX], fs[r, TOOLY], fs[r, TX], fs[r, TY], now - t0, fp[r, VR], fp[r, ACC]
            )
            fs[r, TOOLX] = x
            fs[r, TOOLY] = y
            top = True
        elif pc == PC_DOWN:
            _span(s, rec, r, S_DOWN, fs[r, DOWN0], now)
            ist[r, DOWN] = 0
            fs[r, NEXTFAIL] = now + _draw(p, s, st, r, MTBF)
            if waits:
                _free(p, s, r, now)
            else:
                decide = True
        if top:
            if now >= fs[r, NEXTFAIL]:  # a due failure takes effect now
                ist[r, DOWN] = 1
                _down(p, s, r, now)
                fs[r, DOWN0] = now
                _schedule(s, r, now + _draw(p, s, st, r, MTTR), NORMAL, PC_DOWN)
            elif waits:
                _free(p, s, r, now)
            else:
                decide = True
        if decide:
            _decide(p, s, st, sc, r, now, v)
        if gs[SEQ] == seq or (gs[SEQ] == seq + 1 and ist[r, ACTIVE] and ist[r, WSEQ] == seq):
            _replay(s, m, r)  # only robot r's wake-up changed
        else:  # the gateway scheduled other robots (an epoch opened, approaches interrupted)
            _calendar(s)
    return gs[STATUS]


@compiled()
def close_open_spans(s, rec, now):
    """Recorder.close_open_spans: a wait or repair still under way at the end counts."""
    ist, fs, gs = s.ist, s.fs, s.gs
    for r in range(ist.shape[0]):
        if ist[r, PC] == PC_HELD:
            _span(s, rec, r, S_WAIT, fs[r, WAIT0], now)
        elif ist[r, PC] == PC_DOWN:
            _span(s, rec, r, S_DOWN, fs[r, DOWN0], now)
        elif ist[r, PC] == PC_HOLDING:
            _span(s, rec, r, S_HOLDING, fs[r, HOLD0], now)
    return gs[STATUS]
