"""The robot's steps in the compiled engine (``twin/robot.py`` and ``twin/bin.py``).

Candidates (parts whose interception point lies in the workspace), the dispatching rules
(SIRO replaying numpy's ``Generator.integers`` on pre-drawn draws), a decision (a pick or a
NooP), claims, breakdown draws and state spans; the event loop (:mod:`twin.fast.kernel`)
runs them at the robot's wake-ups. Functions take the run's structures
(:mod:`twin.fast.structs`): ``p`` parameters, ``s`` state, ``rec`` records, ``st`` streams,
``sc`` scratch.
"""

from __future__ import annotations

import math

from pnp_twin.twin.fast.calendar import _schedule
from pnp_twin.twin.fast.jit import compiled
from pnp_twin.twin.fast.layout import (
    ACC,
    APPROACH,
    BA,
    BASEX,
    BASEY,
    BB,
    BINSIDE,
    BX,
    BY,
    CLAIMED,
    DN,
    DOWN,
    DROBOT,
    EXPIDX,
    EXTERNAL,
    FAILMODE,
    FIFO,
    FILTER,
    FIXED,
    HALF,
    HINT_HI,
    HINT_LO,
    KPICK,
    KPICKS,
    KPLACE,
    KVALUE,
    LASTCLAIM,
    LD,
    LIFO,
    MOUNTX,
    MOUNTY,
    MTBF,
    NEXTFAIL,
    NOOP,
    NOOPPART,
    NOOPSTAMP,
    NORMAL,
    NSPANS,
    PART,
    PC,
    PC_APPROACH,
    PC_HOLDING,
    PC_NOOP,
    PC_PLACE,
    PC_START,
    PRIO,
    QUAD,
    REACH,
    RELEASES,
    RIVALS,
    RULE,
    RULENOW,
    SD,
    SIRO,
    SIROIDX,
    ST_CHOOSE,
    ST_EXPS,
    ST_SIRO,
    ST_SPANS,
    STATUS,
    T0,
    TAPP,
    TICK,
    TOOLX,
    TOOLY,
    TWO,
    TX,
    TY,
    URGENT,
    VAL,
    VR,
    XLO,
    V,
)
from pnp_twin.twin.fast.mathlib import intercept_time, move_time, py_pow

FREE = -1  # holder of a part no robot claimed


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
def _span(s, rec, r, state, start, end):
    sp_i, sp_f, gs = rec.sp_i, rec.sp_f, s.gs
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
def _draw(p, s, st, r, col):
    mean = p.fp[r, col]
    if p.ip[r, FAILMODE] == FIXED:
        return mean
    k = s.ist[r, EXPIDX]
    if k >= st.exps.shape[1]:
        s.gs[STATUS] = ST_EXPS
        return math.inf
    s.ist[r, EXPIDX] = k + 1
    return mean * st.exps[r, k]


@compiled(inline=True)
def _intercept(p, s, q, x, y):
    """Robot.intercept: robot q's interception time of a part now at (x, y)."""
    fp, fs = p.fp, s.fs
    v = p.gp[V]
    dx = x - fs[q, TOOLX]
    dy = y - fs[q, TOOLY]
    acc = fp[q, ACC]
    if acc > 0.0:
        return intercept_time(dx, dy, v, fp[q, VR], acc)
    quad = fp[q, QUAD]
    return (dx * v + math.sqrt(dx * dx * (v * v) + quad * (dx * dx + dy * dy))) / quad


@compiled(inline=True)
def _can_take(p, q, x, y, t):
    """Robot.can_take: met inside robot q's [a, b] and within its reach (its kind checked
    before, so no interception time is computed for a kind it does not pick)."""
    fp = p.fp
    xi = x + p.gp[V] * t
    if not (fp[q, BA] <= xi and xi <= fp[q, BB]):
        return False
    reach = fp[q, REACH]
    if reach > 0.0:
        mx = fp[q, MOUNTX]
        my = fp[q, MOUNTY]
        return (xi - mx) * (xi - mx) + (y - my) * (y - my) <= reach * reach
    return True


@compiled(inline=True)
def _idle(p, s, r, q, now):
    """Robot q is robot r's rival (their x-ranges overlap) and idle (see Robot._yields_to)."""
    fp, ist = p.fp, s.ist
    if q == r or not (fp[q, BA] < fp[r, BB] and fp[r, BA] < fp[q, BB]):
        return False
    if ist[q, DOWN] or ist[q, PC] == PC_PLACE or ist[q, PC] == PC_HOLDING:
        return False  # down, or carrying a part
    return not (ist[q, CLAIMED] >= 0 and s.fs[q, T0] < now)  # approaching an earlier claim


@compiled()
def _idle_rival(p, s, r, now):
    """Whether some rival of robot r is idle now."""
    for q in range(s.ist.shape[0]):
        if _idle(p, s, r, q, now):
            return True
    return False


@compiled()
def _yields_to(p, s, r, kind, x, y, t, now):
    """Robot._yields_to: an idle facing robot intercepts this part sooner (or as soon, and
    comes first in the priority order); one that claimed at ``now`` still counts as idle."""
    for q in range(s.ist.shape[0]):
        if not _idle(p, s, r, q, now) or p.kp[q, kind, KPICKS] == 0.0:
            continue
        t_q = _intercept(p, s, q, x, y)
        if not _can_take(p, q, x, y, t_q):
            continue
        if t_q < t or (t_q == t and p.ip[q, PRIO] < p.ip[r, PRIO]):
            return True
    return False


@compiled(inline=True)
def _keep(sc, n, i, x, y, t):
    """Candidate n is part i, now at (x, y), intercepted after t s."""
    sc.c_i[n] = i
    sc.c_f[n, 0] = x
    sc.c_f[n, 1] = y
    sc.c_f[n, 2] = t


@compiled()
def _filtered_candidates(p, s, st, sc, r, now, lo, hi):
    """Robot._filtered_candidates: the candidates in [lo, hi) passing every test."""
    fed, ys, holder = st.fed, st.ys, s.holder
    v = p.gp[V]
    n = 0
    for i in range(lo, hi):
        if holder[i] != FREE:
            continue
        kind = st.kind[i]
        if p.kp[r, kind, KPICKS] == 0.0:
            continue
        x = v * now - v * fed[i]
        y = ys[i]
        t = _intercept(p, s, r, x, y)
        if not _can_take(p, r, x, y, t):
            continue
        if _yields_to(p, s, r, kind, x, y, t, now):
            continue
        _keep(sc, n, i, x, y, t)
        n += 1
    return n


@compiled()
def _candidates(p, s, st, sc, r, now):
    """Robot._candidates: unclaimed parts whose interception point lies in [a, b]."""
    fp, fs, ist, fed, ys, holder = p.fp, s.fs, s.ist, st.fed, st.ys, s.holder
    v = p.gp[V]
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
    tests = p.ip[r, FILTER]
    if tests == RIVALS and not _idle_rival(p, s, r, now):
        tests = 0  # only rivals to test, and none is idle: the plain loop finds the same
    if tests:
        return _filtered_candidates(p, s, st, sc, r, now, lo, hi)
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
            _keep(sc, n, i, x, y, t)
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
def _choose(p, s, st, sc, r, n):
    """policies.rules applied to the candidates (furthest downstream first)."""
    fp, gp, c_f = p.fp, p.gp, sc.c_f
    rule = p.ip[r, RULE]
    if rule == FIFO:
        return 0
    if rule == LIFO:
        return n - 1
    if rule == SIRO:
        return _lemire(st.siro, s.gs, n)
    if rule == SD or rule == LD:
        best = 0
        near = (rule == SD) == (fp[r, BINSIDE] > 0.0)  # the largest y, else the smallest
        for k in range(1, n):
            if near and c_f[k, 1] > c_f[best, 1]:
                best = k
            elif not near and c_f[k, 1] < c_f[best, 1]:
                best = k
        return best
    # SPT: the smallest full cycle time, first of equals; VAL: the highest value first
    v = gp[V]
    bx = fp[r, BX]
    by = fp[r, BY]
    two = gp[TWO]
    half = gp[HALF]
    kp = p.kp
    best = 0
    best_c = math.inf
    best_v = -math.inf
    for k in range(n):
        kind = st.kind[sc.c_i[k]]
        t = c_f[k, 2]
        xi = c_f[k, 0] + v * t
        d = py_pow(py_pow(bx - xi, two) + py_pow(by - c_f[k, 1], two), half)
        transfer = move_time(d, fp[r, VR], fp[r, ACC])
        c = t + kp[r, kind, KPICK] + transfer + kp[r, kind, KPLACE]
        value = kp[r, kind, KVALUE] if rule == VAL else 0.0
        if k == 0 or value > best_v or (value == best_v and c < best_c):
            best = k
            best_c = c
            best_v = value
    return best


@compiled()
def _next_entry(gp, fed, holder, now, x, hint, floor):
    """Belt.next_entry: time until the next unclaimed part upstream of x reaches it, and
    that part's index (len(fed) and inf when there is none). Every part from the first
    upstream of x up to ``floor`` is known to be claimed (the answer of the robot's last
    search, no claim released since): the search starts there."""
    v = gp[V]
    lag = x / v
    i = _bisect(fed, now - lag, True, hint)
    if floor > i:
        i = floor
    n = fed.shape[0]
    while i < n and (holder[i] != FREE or fed[i] + lag <= now):
        i += 1
    if i >= n:
        return math.inf, n
    return fed[i] + lag - now, i


@compiled(inline=True)
def _noop(p, s, st, r, now):
    """Robot._noop: wait until the next part enters the workspace or one belt tick passes."""
    fp, gp, ist, gs = p.fp, p.gp, s.ist, s.gs
    s.counts[r, NOOP] += 1
    floor = ist[r, NOOPPART] if ist[r, NOOPSTAMP] == gs[RELEASES] else 0
    wait, ist[r, NOOPPART] = _next_entry(
        gp, st.fed, s.holder, now, fp[r, BA], ist[r, HINT_HI], floor
    )
    ist[r, NOOPSTAMP] = gs[RELEASES]
    tick = gp[TICK]
    if tick < wait:
        wait = tick
    if now + wait <= now:  # too small to move the clock: a NooP must let time pass
        wait = tick
    _schedule(s, r, now + wait, NORMAL, PC_NOOP)


@compiled()
def _decide(p, s, st, sc, r, now, v):
    """Look at the candidates: pick one (claim it, start the approach) or take a NooP."""
    fs, ist, gs = s.fs, s.ist, s.gs
    n = _candidates(p, s, st, sc, r, now)
    fs[r, T0] = now
    if n == 0:
        _noop(p, s, st, r, now)
        return
    rule = p.ip[r, RULE]
    if rule == EXTERNAL:  # the caller chooses: choose_external resumes
        gs[STATUS] = ST_CHOOSE
        gs[DROBOT] = r
        gs[DN] = n
        return
    k = _choose(p, s, st, sc, r, n)
    s.counts[r, rule] += 1
    _claim(s, sc, r, now, v, k, rule)
    pick = p.kp[r, st.kind[ist[r, PART]], KPICK]
    _schedule(s, r, now + (fs[r, TAPP] + pick), NORMAL, PC_APPROACH)


@compiled()
def choose_external(p, s, st, sc, k, rule):
    """The caller's answer to ST_CHOOSE: candidate ``k``, recorded under rule code ``rule``
    (a code of layout.RULE_NAMES, a caller's own code above them, or NO_RULE)."""
    fs, gs = s.fs, s.gs
    r = gs[DROBOT]
    now = fs[r, T0]
    _claim(s, sc, r, now, p.gp[V], k, rule)
    pick = p.kp[r, st.kind[s.ist[r, PART]], KPICK]
    _schedule(s, r, now + (fs[r, TAPP] + pick), NORMAL, PC_APPROACH)
    gs[STATUS] = 0


@compiled()
def decline_external(p, s, st):
    """The caller's answer to ST_CHOOSE when its policy picks nothing: a NooP."""
    r = s.gs[DROBOT]
    _noop(p, s, st, r, s.fs[r, T0])
    s.gs[STATUS] = 0


@compiled(inline=True)
def _claim(s, sc, r, now, v, k, rule):
    """Claim candidate ``k`` for the approach (Robot.working after the policy's answer)."""
    fs, ist, holder, left_at, c_f = s.fs, s.ist, s.holder, s.left_at, sc.c_f
    part = sc.c_i[k]
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
def start_robots(p, s, st):
    """Robot.__init__ and Line start: first failures drawn, processes initialised in order."""
    fp, fs, ist = p.fp, s.fs, s.ist
    for r in range(ist.shape[0]):
        fs[r, TOOLX] = fp[r, BASEX]
        fs[r, TOOLY] = fp[r, BASEY]
        fs[r, NEXTFAIL] = math.inf
        fs[r, APPROACH] = -math.inf
        ist[r, CLAIMED] = -1
        ist[r, LASTCLAIM] = -1
        if p.ip[r, FAILMODE] != 0:
            fs[r, NEXTFAIL] = _draw(p, s, st, r, MTBF)
    for r in range(ist.shape[0]):
        _schedule(s, r, 0.0, URGENT, PC_START)
