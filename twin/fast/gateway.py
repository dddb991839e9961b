"""The gateway's decision epochs in the compiled engine (``twin/gateway.py``, branch for branch).

A free robot reports here under t_all and t_any (and in hold mode); an epoch opens for the
robots flagged in a column of ``ist``: they are scheduled in robot order (upstream first), or
in hold mode marked pending until the caller answers (:func:`release`). ``p`` and ``s`` are
the run's parameters and state (:mod:`twin.fast.structs`).

The two the event loop calls, :func:`_free` and :func:`_down`, are inlined in it: a call
passes each array of the structures as separate arguments (about 90 here), and in hold
mode, where every free robot reports here, that cost the vector env's step about a fifth
of its speed (``bench/bench_vector_env.py --threads 1``, 256 lines). Inlining
:func:`_open` as well made the step slower again, so it stays a call.
"""

from __future__ import annotations

from pnp_twin.twin.fast.calendar import _schedule
from pnp_twin.twin.fast.jit import compiled
from pnp_twin.twin.fast.layout import (
    ACTIVE,
    APPROACH,
    CLAIMED,
    DOWN,
    EPOCHS,
    EXPECTED,
    HOLD,
    MASK,
    NORMAL,
    NOW,
    NPENDING,
    PC,
    PC_HELD,
    PC_INTERRUPT,
    PENDING,
    SCHEME,
    ST_EPOCH,
    STATUS,
    T_ALL,
    T_ANY,
    T_CONTINUE,
    URGENT,
    WAIT0,
    WAITING,
)


@compiled()
def _open(p, s, col, now):
    """Open an epoch for the robots flagged in column ``col`` of ``ist`` (in hold mode: mark
    them pending; :func:`release` resumes them once the caller has set their rules)."""
    ist, gs = s.ist, s.gs
    gs[EPOCHS] += 1
    for i in range(ist.shape[0]):  # in robot order, so upstream robots claim first
        if ist[i, col]:
            ist[i, WAITING] = 0
            if p.gi[HOLD]:
                ist[i, PENDING] = 1
                gs[NPENDING] += 1
            else:
                _schedule(s, i, now, NORMAL, PC_HELD)


@compiled()
def release(s):
    """Gateway.release: resume the pending robots, in robot order, now."""
    ist, gs = s.ist, s.gs
    now = s.gf[NOW]
    for i in range(ist.shape[0]):
        if ist[i, PENDING]:
            ist[i, PENDING] = 0
            _schedule(s, i, now, NORMAL, PC_HELD)
    gs[NPENDING] = 0
    if gs[STATUS] == ST_EPOCH:
        gs[STATUS] = 0


@compiled()
def _maybe_all(p, s, now):
    ist = s.ist
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
        _open(p, s, MASK, now)


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
def _join_any(p, s, r, now):
    fs, ist = s.fs, s.ist
    n = ist.shape[0]
    some, _ = _expected_waiting(ist)
    if not some:
        ist[r, EXPECTED] = 1
        for o in range(n):
            if o != r and ist[o, CLAIMED] >= 0 and fs[o, APPROACH] > now:
                _schedule(s, o, now, URGENT, PC_INTERRUPT)
                ist[o, EXPECTED] = 1
    else:
        ist[r, EXPECTED] = 1
    _, sub = _expected_waiting(ist)
    if sub:
        for i in range(n):
            ist[i, MASK] = ist[i, EXPECTED]
            ist[i, EXPECTED] = 0
        _open(p, s, MASK, now)


@compiled(inline=True)
def _down(p, s, r, now):
    ist = s.ist
    ist[r, WAITING] = 0
    ist[r, EXPECTED] = 0
    if p.gi[SCHEME] == T_ALL:
        _maybe_all(p, s, now)
    elif p.gi[SCHEME] == T_ANY:
        some, sub = _expected_waiting(ist)
        if some and sub:  # the epoch opens, and the next free robot starts a new one
            for i in range(ist.shape[0]):
                ist[i, MASK] = ist[i, EXPECTED]
                ist[i, EXPECTED] = 0
            _open(p, s, MASK, now)


@compiled(inline=True)
def _free(p, s, r, now):
    ist, gi = s.ist, p.gi
    ist[r, PC] = PC_HELD
    ist[r, ACTIVE] = 0
    s.fs[r, WAIT0] = now
    ist[r, WAITING] = 1
    if gi[SCHEME] == T_CONTINUE:  # in hold mode only: an epoch of one
        for i in range(ist.shape[0]):
            ist[i, MASK] = 0
        ist[r, MASK] = 1
        _open(p, s, MASK, now)
    elif gi[SCHEME] == T_ALL:
        _maybe_all(p, s, now)
    else:
        _join_any(p, s, r, now)
