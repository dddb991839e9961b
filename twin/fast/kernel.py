"""The compiled event loop: the SimPy twin's robots, gateway and bins as a state machine.

Each robot is one slot of arrays. SimPy's event queue orders events by (time, priority,
creation number); every robot has at most one live wake-up (a timeout, a release of its
decision hold or a t_any interruption), so the loop scans the N slots for the smallest
(time, priority, sequence) and resumes that robot at its program counter. Sequence numbers
are handed out in the order the twin creates its events, so equal-time events resolve the
same way. Every branch mirrors ``twin/robot.py``, ``twin/gateway.py`` and ``twin/bin.py``;
the arithmetic is written operation for operation as there (see :mod:`twin.fast.mathlib`).

State lives in plain arrays (see :mod:`twin.fast.layout` for the column names), so a run can
be copied at any point and continued.
"""

from __future__ import annotations

import math

from pnp_twin.twin.fast.jit import compiled
from pnp_twin.twin.fast.layout import (
    ACC,
    ACTIVE,
    APPROACH,
    BA,
    BASEX,
    BASEY,
    BB,
    BINCOUNT,
    BINREADY,
    BOXES,
    BX,
    BY,
    CAPACITY,
    CHANGE,
    CLAIMED,
    DN,
    DOWN,
    DOWN0,
    DROBOT,
    EPOCHS,
    EXP_MARGIN,
    EXPECTED,
    EXPIDX,
    EXPONENTIAL,
    EXTERNAL,
    FAILMODE,
    FIFO,
    FIXED,
    HALF,
    HINT_HI,
    HINT_LO,
    HOLD,
    LASTCLAIM,
    LD,
    LIFO,
    MASK,
    MTBF,
    MTTR,
    NEXTFAIL,
    NOOP,
    NOOPPART,
    NORMAL,
    NOW,
    NPENDING,
    NSPANS,
    PART,
    PC,
    PC_APPROACH,
    PC_DOWN,
    PC_HELD,
    PC_INTERRUPT,
    PC_NOOP,
    PC_PLACE,
    PC_START,
    PENDING,
    PICK,
    PLACE,
    QUAD,
    ROOM_EXPS,
    ROOM_SIRO,
    ROOM_SPANS,
    ROOMFOR,
    RULE,
    RULENOW,
    S_BLOCKED,
    S_DOWN,
    S_INTERRUPTED,
    S_NOOP,
    S_WAIT,
    SCHEME,
    SD,
    SEQ,
    SIRO,
    SIRO_MARGIN,
    SIROIDX,
    SPAN_MARGIN,
    ST_CHOOSE,
    ST_EPOCH,
    ST_EXPS,
    ST_ROOM,
    ST_SIRO,
    ST_SPANS,
    STATUS,
    T0,
    T_ALL,
    T_ANY,
    T_CONTINUE,
    TAPP,
    TICK,
    TOOLX,
    TOOLY,
    TWO,
    TX,
    TY,
    URGENT,
    VR,
    WAIT0,
    WAITING,
    WAKE,
    WPRIO,
    WSEQ,
    XLO,
    V,
)
from pnp_twin.twin.fast.mathlib import intercept_time, move_time, position_along, py_hypot, py_pow

FREE = -1


@compiled(inline=True)
def _bisect(a, x, right, hint):
    """bisect_left (or bisect_right) of sorted ``a``, galloping out from index ``hint``.

    The answer does not depend on the hint (it is the unique insertion point); a good hint
    (the robot's previous answer: its queries move forward with time) makes it cheap.
    """
    n = a.shape[0]
    h = min(max(hint, 0), n)
    if h < n and (a[h] <= x if right else a[h] < x):  # answer is above h
        lo = h + 1
        step = 1
        hi = lo
        while hi < n and (a[hi] <= x if right else a[hi] < x):
            lo = hi + 1
            hi = lo + step
            step *= 2
        hi = min(hi, n)
    else:  # answer is at or below h
        hi = h
        step = 1
        lo = hi
        while lo > 0 and not (a[lo - 1] <= x if right else a[lo - 1] < x):
            hi = lo - 1
            lo = max(hi - step, 0)
            step *= 2
    while lo < hi:
        mid = (lo + hi) >> 1
        if a[mid] <= x if right else a[mid] < x:
            lo = mid + 1
        else:
            hi = mid
    return lo


@compiled(inline=True)
def _schedule(fs, ist, gs, r, at, prio, pc):
    fs[r, WAKE] = at
    ist[r, WPRIO] = prio
    ist[r, WSEQ] = gs[SEQ]
    gs[SEQ] += 1
    ist[r, ACTIVE] = 1
    ist[r, PC] = pc


@compiled(inline=True)
def _span(gs, sp_i, sp_f, r, state, start, end):
    if end > start and sp_i.shape[0] > 0:  # a run given no span buffer records no spans
        k = gs[NSPANS]
        if k >= sp_i.shape[0]:
            gs[STATUS] = ST_SPANS
            return
        sp_i[k, 0] = r
        sp_i[k, 1] = state
        sp_f[k, 0] = start
        sp_f[k, 1] = end
        gs[NSPANS] = k + 1


@compiled(inline=True)
def _draw(fp, ip, ist, gs, exps, r, col):
    mean = fp[r, col]
    if ip[r, FAILMODE] == FIXED:
        return mean
    k = ist[r, EXPIDX]
    if k >= exps.shape[1]:
        gs[STATUS] = ST_EXPS
        return math.inf
    ist[r, EXPIDX] = k + 1
    return mean * exps[r, k]


@compiled()
def _candidates(fp, fs, ist, gp, fed, ys, holder, now, r, c_i, c_f):
    """Robot._candidates: unclaimed parts whose interception point lies in [a, b]."""
    v = gp[V]
    px = fs[r, TOOLX]
    py = fs[r, TOOLY]
    a = fp[r, BA]
    b = fp[r, BB]
    quad = fp[r, QUAD]
    acc = fp[r, ACC]
    vv = v * v
    vnow = v * now
    x_lo = fp[r, XLO]
    lo_x = x_lo
    if 0.0 > x_lo:
        lo_x = 0.0
    lo = _bisect(fed, now - b / v, False, ist[r, HINT_LO])
    hi = _bisect(fed, now - lo_x / v, True, ist[r, HINT_HI])
    ist[r, HINT_LO] = lo
    ist[r, HINT_HI] = hi
    n = 0
    for i in range(lo, hi):
        if holder[i] != FREE:
            continue
        x = vnow - v * fed[i]
        y = ys[i]
        dx = x - px
        dy = y - py
        if acc > 0.0:
            t = intercept_time(dx, dy, v, fp[r, VR], acc)
        else:
            t = (dx * v + math.sqrt(dx * dx * vv + quad * (dx * dx + dy * dy))) / quad
        xi = x + v * t
        if a <= xi and xi <= b:
            c_i[n] = i
            c_f[n, 0] = x
            c_f[n, 1] = y
            c_f[n, 2] = t
            n += 1
    return n


@compiled()
def _lemire(siro, gs, n):
    """numpy Generator.integers(n) on a pre-drawn stream of next_uint32 outputs."""
    rng = n - 1
    if rng == 0:
        return 0
    excl = n
    k = gs[SIROIDX]
    if k >= siro.shape[0]:
        gs[STATUS] = ST_SIRO
        return 0
    m = siro[k] * excl
    k += 1
    left = m & 0xFFFFFFFF
    if left < excl:
        thr = (0xFFFFFFFF - rng) % excl
        while left < thr:
            if k >= siro.shape[0]:
                gs[STATUS] = ST_SIRO
                gs[SIROIDX] = k
                return 0
            m = siro[k] * excl
            k += 1
            left = m & 0xFFFFFFFF
    gs[SIROIDX] = k
    return m >> 32


@compiled()
def _choose(fp, ip, gp, gs, siro, r, n, c_f):
    """policies.rules applied to the candidates (furthest downstream first)."""
    rule = ip[r, RULE]
    if rule == FIFO:
        return 0
    if rule == LIFO:
        return n - 1
    if rule == SIRO:
        return _lemire(siro, gs, n)
    if rule == SD or rule == LD:
        best = 0
        for k in range(1, n):
            if rule == SD and c_f[k, 1] > c_f[best, 1]:
                best = k
            elif rule == LD and c_f[k, 1] < c_f[best, 1]:
                best = k
        return best
    # SPT: the smallest full cycle time, first of equals
    v = gp[V]
    bx = fp[r, BX]
    by = fp[r, BY]
    two = gp[TWO]
    half = gp[HALF]
    best = 0
    best_c = math.inf
    pick = fp[r, PICK]
    place = fp[r, PLACE]
    for k in range(n):
        t = c_f[k, 2]
        xi = c_f[k, 0] + v * t
        d = py_pow(py_pow(bx - xi, two) + py_pow(by - c_f[k, 1], two), half)
        transfer = move_time(d, fp[r, VR], fp[r, ACC])
        c = t + pick + transfer + place
        if k == 0 or c < best_c:
            best = k
            best_c = c
    return best


@compiled()
def _next_entry(gp, fed, holder, now, x, hint):
    """Belt.next_entry: time until the next unclaimed part upstream of x reaches it, and
    that part's index (len(fed) and inf when there is none)."""
    v = gp[V]
    lag = x / v
    i = _bisect(fed, now - lag, True, hint)
    n = fed.shape[0]
    while i < n and (holder[i] != FREE or fed[i] + lag <= now):
        i += 1
    if i >= n:
        return math.inf, n
    return fed[i] + lag - now, i


# -- the gateway ---------------------------------------------------------------------------
@compiled()
def _open(fs, ist, gi, gs, col, now):
    """Open an epoch for the robots flagged in column ``col`` of ``ist`` (in hold mode: mark
    them pending; :func:`release` resumes them once the caller has set their rules)."""
    gs[EPOCHS] += 1
    for i in range(ist.shape[0]):  # in robot order, so upstream robots claim first
        if ist[i, col]:
            ist[i, WAITING] = 0
            if gi[HOLD]:
                ist[i, PENDING] = 1
                gs[NPENDING] += 1
            else:
                _schedule(fs, ist, gs, i, now, NORMAL, PC_HELD)


@compiled()
def release(fs, ist, gs, now):
    """Gateway.release: resume the pending robots, in robot order."""
    for i in range(ist.shape[0]):
        if ist[i, PENDING]:
            ist[i, PENDING] = 0
            _schedule(fs, ist, gs, i, now, NORMAL, PC_HELD)
    gs[NPENDING] = 0
    if gs[STATUS] == ST_EPOCH:
        gs[STATUS] = 0


@compiled()
def _maybe_all(fs, ist, gi, gs, now):
    n = ist.shape[0]
    some = False
    for i in range(n):
        if ist[i, DOWN] == 0:
            if ist[i, WAITING] == 0:
                return
            some = True
    if some:
        for i in range(n):
            ist[i, MASK] = 1 - ist[i, DOWN]
        _open(fs, ist, gi, gs, MASK, now)


@compiled(inline=True)
def _expected_waiting(ist):
    """(expected is non-empty, expected <= waiting)."""
    some = False
    for i in range(ist.shape[0]):
        if ist[i, EXPECTED]:
            some = True
            if not ist[i, WAITING]:
                return some, False
    return some, True


@compiled()
def _join_any(fs, ist, gi, gs, r, now):
    n = ist.shape[0]
    some, _ = _expected_waiting(ist)
    if not some:
        ist[r, EXPECTED] = 1
        for o in range(n):
            if o != r and ist[o, CLAIMED] >= 0 and fs[o, APPROACH] > now:
                _schedule(fs, ist, gs, o, now, URGENT, PC_INTERRUPT)
                ist[o, EXPECTED] = 1
    else:
        ist[r, EXPECTED] = 1
    _, sub = _expected_waiting(ist)
    if sub:
        for i in range(n):
            ist[i, MASK] = ist[i, EXPECTED]
            ist[i, EXPECTED] = 0
        _open(fs, ist, gi, gs, MASK, now)


@compiled()
def _down(fs, ist, gi, gs, r, now):
    ist[r, WAITING] = 0
    ist[r, EXPECTED] = 0
    if gi[SCHEME] == T_ALL:
        _maybe_all(fs, ist, gi, gs, now)
    elif gi[SCHEME] == T_ANY:
        some, sub = _expected_waiting(ist)
        if some and sub:  # the epoch opens, and the next free robot starts a new one
            for i in range(ist.shape[0]):
                ist[i, MASK] = ist[i, EXPECTED]
                ist[i, EXPECTED] = 0
            _open(fs, ist, gi, gs, MASK, now)


@compiled()
def _free(fs, ist, gi, gs, r, now):
    ist[r, PC] = PC_HELD
    ist[r, ACTIVE] = 0
    fs[r, WAIT0] = now
    ist[r, WAITING] = 1
    if gi[SCHEME] == T_CONTINUE:  # in hold mode only: an epoch of one
        for i in range(ist.shape[0]):
            ist[i, MASK] = 0
        ist[r, MASK] = 1
        _open(fs, ist, gi, gs, MASK, now)
    elif gi[SCHEME] == T_ALL:
        _maybe_all(fs, ist, gi, gs, now)
    else:
        _join_any(fs, ist, gi, gs, r, now)


# -- the robot -----------------------------------------------------------------------------
@compiled(inline=True)
def _short_of_room(ip, ist, gs, sp_i, siro, exps, r):
    """Before robot r's event: would a buffer or pre-drawn stream it may use run out? Then
    stop with ST_ROOM (the state untouched), so the caller can grow it and carry on."""
    room = -1
    if sp_i.shape[0] > 0 and gs[NSPANS] + SPAN_MARGIN > sp_i.shape[0]:
        room = ROOM_SPANS
    elif ip[r, RULE] == SIRO and gs[SIROIDX] + SIRO_MARGIN > siro.shape[0]:
        room = ROOM_SIRO
    elif ip[r, FAILMODE] == EXPONENTIAL and ist[r, EXPIDX] + EXP_MARGIN > exps.shape[1]:
        room = ROOM_EXPS
    if room < 0:
        return False
    gs[STATUS] = ST_ROOM
    gs[ROOMFOR] = room
    gs[DROBOT] = r
    return True


@compiled()
def run_events(
    fp, ip, gp, gi, fs, ist, gs, gf, fed, ys, holder, left_at,
    rec_i, rec_f, sp_i, sp_f, counts, siro, exps, c_i, c_f, stop_at,
):  # fmt: skip
    """Process events with time < stop_at; returns the status: 0 (reached stop_at),
    ST_CHOOSE, ST_EPOCH, ST_ROOM (call again once grown) or, should an event still run out
    of room, ST_SPANS / ST_SIRO / ST_EXPS."""
    n_rob = ist.shape[0]
    v = gp[V]
    scheme = gi[SCHEME]
    capacity = gi[CAPACITY]
    waits = scheme != T_CONTINUE or gi[HOLD]  # a free robot reports to the gateway
    while gs[STATUS] == 0:
        r = -1
        for i in range(n_rob):
            if ist[i, ACTIVE]:
                if r < 0:
                    r = i
                else:
                    w, bw = fs[i, WAKE], fs[r, WAKE]
                    if w < bw or (
                        w == bw
                        and (
                            ist[i, WPRIO] < ist[r, WPRIO]
                            or (ist[i, WPRIO] == ist[r, WPRIO] and ist[i, WSEQ] < ist[r, WSEQ])
                        )
                    ):
                        r = i
        if gs[NPENDING] > 0 and (r < 0 or fs[r, WAKE] > gf[NOW]):
            gs[STATUS] = ST_EPOCH  # the epoch's instant is over: the caller answers it
            break
        if r < 0 or fs[r, WAKE] >= stop_at:
            break
        if _short_of_room(ip, ist, gs, sp_i, siro, exps, r):
            break  # ST_ROOM: the caller grows the buffer or stream and calls again
        now = fs[r, WAKE]
        gf[NOW] = now
        ist[r, ACTIVE] = 0
        pc = ist[r, PC]
        top = False  # go to the top of the loop (failure check)
        decide = False  # go straight to the candidates
        if pc == PC_START:
            top = True
        elif pc == PC_NOOP:
            _span(gs, sp_i, sp_f, r, S_NOOP, fs[r, T0], now)
            top = True
        elif pc == PC_HELD:
            _span(gs, sp_i, sp_f, r, S_WAIT, fs[r, WAIT0], now)
            decide = True
        elif pc == PC_APPROACH:  # gripped: move to the bin and place
            part = ist[r, PART]
            ist[r, CLAIMED] = -1
            t0 = fs[r, T0]
            rec_i[part, 0] = r
            rec_i[part, 1] = ist[r, RULENOW]
            rec_f[part, 0] = t0
            rec_f[part, 1] = t0 + fs[r, TAPP]
            v_r = fp[r, VR]
            acc = fp[r, ACC]
            dist = py_hypot(fp[r, BX] - fs[r, TX], fp[r, BY] - fs[r, TY])
            if acc <= 0.0:
                arrive = now + dist / v_r
            else:
                arrive = now + move_time(dist, v_r, acc)
            start = arrive
            if fs[r, BINREADY] > arrive:
                start = fs[r, BINREADY]
            done = start + fp[r, PLACE]
            ist[r, BINCOUNT] += 1
            if capacity and ist[r, BINCOUNT] >= capacity:
                ist[r, BINCOUNT] = 0
                ist[r, BOXES] += 1
                fs[r, BINREADY] = done + gp[CHANGE]
            blocked = start - arrive
            rec_f[part, 2] = done
            if blocked > 0.0:
                rec_f[part, 3] = blocked
                _span(gs, sp_i, sp_f, r, S_BLOCKED, arrive, arrive + blocked)
            _schedule(fs, ist, gs, r, now + (done - now), NORMAL, PC_PLACE)
        elif pc == PC_PLACE:
            fs[r, TOOLX] = fp[r, BX]
            fs[r, TOOLY] = fp[r, BY]
            top = True
        elif pc == PC_INTERRUPT:
            part = ist[r, PART]
            holder[part] = FREE
            left_at[part] = math.inf
            ist[r, CLAIMED] = -1
            t0 = fs[r, T0]
            _span(gs, sp_i, sp_f, r, S_INTERRUPTED, t0, now)
            x, y = position_along(
                fs[r, TOOLX], fs[r, TOOLY], fs[r, TX], fs[r, TY], now - t0, fp[r, VR], fp[r, ACC]
            )
            fs[r, TOOLX] = x
            fs[r, TOOLY] = y
            top = True
        elif pc == PC_DOWN:
            _span(gs, sp_i, sp_f, r, S_DOWN, fs[r, DOWN0], now)
            ist[r, DOWN] = 0
            fs[r, NEXTFAIL] = now + _draw(fp, ip, ist, gs, exps, r, MTBF)
            if waits:
                _free(fs, ist, gi, gs, r, now)
            else:
                decide = True
        if top:
            if now >= fs[r, NEXTFAIL]:  # a due failure takes effect now
                ist[r, DOWN] = 1
                _down(fs, ist, gi, gs, r, now)
                fs[r, DOWN0] = now
                _schedule(
                    fs, ist, gs, r, now + _draw(fp, ip, ist, gs, exps, r, MTTR), NORMAL, PC_DOWN
                )
            elif waits:
                _free(fs, ist, gi, gs, r, now)
            else:
                decide = True
        if decide:
            _decide(
                fp, ip, gp, fs, ist, gs, fed, ys, holder, left_at, counts, siro, c_i, c_f, r, now, v
            )
    return gs[STATUS]


@compiled()
def _decide(fp, ip, gp, fs, ist, gs, fed, ys, holder, left_at, counts, siro, c_i, c_f, r, now, v):
    """Look at the candidates: pick one (claim it, start the approach) or take a NooP."""
    n = _candidates(fp, fs, ist, gp, fed, ys, holder, now, r, c_i, c_f)
    fs[r, T0] = now
    if n == 0:
        counts[r, NOOP] += 1
        wait, ist[r, NOOPPART] = _next_entry(gp, fed, holder, now, fp[r, BA], ist[r, HINT_HI])
        tick = gp[TICK]
        if tick < wait:
            wait = tick
        if now + wait <= now:  # too small to move the clock: a NooP must let time pass
            wait = tick
        _schedule(fs, ist, gs, r, now + wait, NORMAL, PC_NOOP)
        return
    rule = ip[r, RULE]
    if rule == EXTERNAL:  # the caller chooses: choose_external resumes
        gs[STATUS] = ST_CHOOSE
        gs[DROBOT] = r
        gs[DN] = n
        return
    k = _choose(fp, ip, gp, gs, siro, r, n, c_f)
    counts[r, rule] += 1
    _claim(fs, ist, holder, left_at, c_i, c_f, r, now, v, k, rule)
    _schedule(fs, ist, gs, r, now + (fs[r, TAPP] + fp[r, PICK]), NORMAL, PC_APPROACH)


@compiled()
def choose_external(fp, gp, fs, ist, gs, holder, left_at, c_i, c_f, k, rule):
    """The caller's answer to ST_CHOOSE: candidate ``k``, recorded under rule code ``rule``
    (a code of layout.RULE_NAMES, a caller's own code above them, or NO_RULE)."""
    r = gs[DROBOT]
    now = fs[r, T0]
    _claim(fs, ist, holder, left_at, c_i, c_f, r, now, gp[V], k, rule)
    _schedule(fs, ist, gs, r, now + (fs[r, TAPP] + fp[r, PICK]), NORMAL, PC_APPROACH)
    gs[STATUS] = 0


@compiled(inline=True)
def _claim(fs, ist, holder, left_at, c_i, c_f, r, now, v, k, rule):
    """Claim candidate ``k`` for the approach (Robot.working after the policy's answer)."""
    part = c_i[k]
    t = c_f[k, 2]
    fs[r, TX] = c_f[k, 0] + v * t
    fs[r, TY] = c_f[k, 1]
    fs[r, TAPP] = t
    holder[part] = r
    left_at[part] = now + t
    ist[r, CLAIMED] = part
    ist[r, PART] = part
    ist[r, RULENOW] = rule
    ist[r, LASTCLAIM] = part
    fs[r, APPROACH] = now + t


@compiled()
def start_robots(fp, ip, fs, ist, gs, exps):
    """Robot.__init__ and Line start: first failures drawn, processes initialised in order."""
    for r in range(ist.shape[0]):
        fs[r, TOOLX] = fp[r, BASEX]
        fs[r, TOOLY] = fp[r, BASEY]
        fs[r, NEXTFAIL] = math.inf
        fs[r, APPROACH] = -math.inf
        ist[r, CLAIMED] = -1
        ist[r, LASTCLAIM] = -1
        if ip[r, FAILMODE] != 0:
            fs[r, NEXTFAIL] = _draw(fp, ip, ist, gs, exps, r, MTBF)
    for r in range(ist.shape[0]):
        _schedule(fs, ist, gs, r, 0.0, URGENT, PC_START)


@compiled()
def close_open_spans(ist, fs, gs, sp_i, sp_f, now):
    """Recorder.close_open_spans: a wait or repair still under way at the end counts."""
    for r in range(ist.shape[0]):
        if ist[r, PC] == PC_HELD:
            _span(gs, sp_i, sp_f, r, S_WAIT, fs[r, WAIT0], now)
        elif ist[r, PC] == PC_DOWN:
            _span(gs, sp_i, sp_f, r, S_DOWN, fs[r, DOWN0], now)
    return gs[STATUS]
