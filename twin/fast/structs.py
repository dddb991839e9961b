"""The kernel's arrays in five named structures: every kernel function takes these.

A run is parameters (what it reads and never changes, but the rule codes in hold mode),
state (what its events change), records (what it writes for the tables and KPIs), streams
(the part stream and the pre-drawn random draws it consumes) and scratch (a decision's
candidates). Each is a ``NamedTuple`` of numpy arrays: numba passes it as the arrays
themselves (no copy, no allocation), caches functions that take it, and a batch of runs is
the same structure with a leading axis (:func:`state_of` and friends pick one run's rows).
Column names of the 2-D arrays are in :mod:`twin.fast.layout`.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from pnp_twin.twin.fast.jit import compiled


class Params(NamedTuple):
    """What a run reads: per-robot and line parameters."""

    fp: np.ndarray  # float64 (robots, N_FP): workspace, reach, arm, bin, base, MTBF/MTTR
    ip: np.ndarray  # int64 (robots, N_IP): rule code (set anew in hold mode), failure mode
    gp: np.ndarray  # float64 (N_GP,): belt speed, tick, end of run, box change, constants
    gi: np.ndarray  # int64 (N_GI,): termination scheme, bin capacity, hold mode
    kp: np.ndarray  # float64 (robots, kinds, N_KP): picks the kind, grip, release, value
    og: np.ndarray  # float64 (N_OG + 2 slots,): the outfeed (og[OUT_ON] 0: none, bins)


class State(NamedTuple):
    """What a run's events change: a copy of it continues the run from that instant."""

    fs: np.ndarray  # float64 (robots, N_FS): tool, times, wake-up, the event calendar
    ist: np.ndarray  # int64 (robots, N_IS): program counter, claim, bin, flags
    gs: np.ndarray  # int64 (N_GS,): event counter, epochs, stream positions, status
    gf: np.ndarray  # float64 (1,): the clock
    holder: np.ndarray  # int64 (parts,): the robot that claimed each part, -1: none
    left_at: np.ndarray  # float64 (parts,): each claimed part's grip time, inf: on the belt
    counts: np.ndarray  # int64 (robots, rules + NooP): decisions per robot and rule
    taken: np.ndarray  # int64 (containers, slots): outfeed slots reserved (0 rows: none)


class Records(NamedTuple):
    """What a run writes for the record tables and the KPIs."""

    rec_i: np.ndarray  # int64 (parts, 2): picking robot, rule code (-1: not picked)
    # (4 columns with an outfeed: then container and slot placed into, -1: none)
    rec_f: np.ndarray  # float64 (parts, 4): decided, picked, placed (NaN: not), blocked
    # (6 with an outfeed: then when a hold began (NaN: none) and how long it lasted)
    sp_i: np.ndarray  # int32 (room, 2): each state span's robot and state (0 rows: none)
    sp_f: np.ndarray  # float64 (room, 2): its start and end


class Streams(NamedTuple):
    """What a run consumes: the parts fed and the random draws made before it starts."""

    fed: np.ndarray  # float64 (parts,): feed times, sorted (inf: no part, as padding)
    ys: np.ndarray  # float64 (parts,): lateral positions
    siro: np.ndarray  # int64 (k,): the policy stream's raw next_uint32 outputs (SIRO)
    exps: np.ndarray  # float64 (robots, k): standard exponentials (breakdowns)
    kind: np.ndarray  # int64 (parts,): each part's kind code


class Scratch(NamedTuple):
    """A decision's candidates (one row per part, and one more)."""

    c_i: np.ndarray  # int64 (parts + 1,): candidate part indices
    c_f: np.ndarray  # float64 (parts + 1, 3): their x, y and interception time


@compiled(inline=True)
def params_of(p, ip, e):
    """Line e's parameters: shared ones, and its own row of a batch's rule codes ``ip``."""
    return Params(p.fp, ip[e], p.gp, p.gi, p.kp, p.og)


@compiled(inline=True)
def state_of(b, e):
    """Line e's state in a batch of states (a view)."""
    return State(
        b.fs[e], b.ist[e], b.gs[e], b.gf[e], b.holder[e], b.left_at[e], b.counts[e], b.taken[e]
    )


@compiled(inline=True)
def records_of(b, k):
    """Row k of a batch of records (a view)."""
    return Records(b.rec_i[k], b.rec_f[k], b.sp_i[k], b.sp_f[k])


@compiled(inline=True)
def streams_of(b, e):
    """Line e's streams in a batch of streams (a view)."""
    return Streams(b.fed[e], b.ys[e], b.siro[e], b.exps[e], b.kind[e])


@compiled(inline=True)
def scratch_of(b, k):
    """Row k of a batch of scratch arrays (a view)."""
    return Scratch(b.c_i[k], b.c_f[k])
