"""What-if continuations of a run from one decision: every choice x every sampled future.

A :class:`~twin.fast.engine.FastLine` stopped at a decision (ST_CHOOSE: a robot with the
rule code EXTERNAL has candidates) is forked; :func:`continue_each` then plays, in one
compiled call, each candidate choice under each sampled future (the parts fed up to the
decision kept, later arrivals redrawn: :func:`twin.feeder.splice`) with a rule for every
robot afterwards, up to a stop time, and counts the parts fed in a window that were gripped.

Each continuation is the run the SimPy twin makes when it replays the same choices from
t = 0 on the spliced stream (``Line(parts=future)``): events before the decision see only
parts already fed, except the end of a NooP, which waits for the next part to enter (the
feeder's schedule is known). A NooP under way at the decision that was timed by a part the
future redraws is therefore timed again from the future's stream, as the replay times it.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from pnp_twin.twin.fast import layout as L
from pnp_twin.twin.fast.engine import FastLine
from pnp_twin.twin.fast.jit import compiled
from pnp_twin.twin.fast.kernel import choose_external, run_events
from pnp_twin.twin.fast.structs import Records, Scratch, State, Streams

Future = tuple[np.ndarray, np.ndarray] | tuple[np.ndarray, np.ndarray, np.ndarray]
"""A stream to continue on: (fed, y), one kind of part, or (fed, y, kind codes)."""


@compiled()
def _retime_noops(p, s, fed, n, n_kept):
    """NooPs timed by a part index >= n_kept (or by none) wait for this stream's next part."""
    fp, gp, fs, ist = p.fp, p.gp, s.fs, s.ist
    v = gp[L.V]
    tick = gp[L.TICK]
    for q in range(ist.shape[0]):
        if ist[q, L.ACTIVE] and ist[q, L.PC] == L.PC_NOOP and ist[q, L.NOOPPART] >= n_kept:
            now = fs[q, L.T0]
            wait = math.inf
            if n > n_kept:  # the first redrawn part: unclaimed, entering after now
                wait = fed[n_kept] + fp[q, L.BA] / v - now
            if tick < wait:
                wait = tick
            if now + wait <= now:
                wait = tick
            fs[q, L.WAKE] = now + wait
            ist[q, L.NOOPPART] = n_kept if n > n_kept else n


@compiled()
def _copy(src, dst, rows, fill):
    """dst[:rows] = src[:rows], dst[rows:] = fill (2-D, no temporary)."""
    for i in range(dst.shape[0]):
        for c in range(dst.shape[1]):
            dst[i, c] = src[i, c] if i < rows else fill


@compiled()
def _continue_all(p, at, work, st0, futures, picks, rule, stop_at, window, totals):
    """Every (future, pick) continuation; totals[j] sums the window's grips over futures.

    ``at``: the line at its decision, ``work``: where each continuation runs (each a
    (:class:`~twin.fast.structs.State`, :class:`~twin.fast.structs.Records`,
    :class:`~twin.fast.structs.Scratch`)); ``st0``: the line's streams (their pre-drawn
    draws). ``futures`` = (feds, ys, lens, n_kept, kinds): one future per row of ``feds``/``ys``/
    ``kinds`` (each part's kind code),
    padded with fed = inf past ``lens[m]`` (the kernel sees no part there); the work arrays
    have one row per padded part. ``window``: (lo, hi), the feed times whose grips count."""
    s0, rec0, sc0 = at
    s, rec, sc = work
    feds, ys, lens, n_kept, kinds = futures
    lo, hi = window
    fs0, ist0, gs0, gf0, holder0, left_at0, counts0, _ = s0  # no outfeed (bind_run refuses)
    fs, ist, gs, gf, holder, left_at, counts, _ = s
    rec_i, rec_f = rec.rec_i, rec.rec_f
    for m in range(feds.shape[0]):
        n = lens[m]
        fed = feds[m]
        st = Streams(fed, ys[m], st0.siro, st0.exps, kinds[m])
        for j in range(picks.shape[0]):
            _copy(fs0, fs, fs.shape[0], 0.0)
            _copy(ist0, ist, ist.shape[0], 0)
            _copy(counts0, counts, counts.shape[0], 0)
            for i in range(gs.shape[0]):
                gs[i] = gs0[i]
            gf[0] = gf0[0]
            for i in range(gs0[L.DN]):  # the decision's candidates (the rest is scratch)
                sc.c_i[i] = sc0.c_i[i]
                for c in range(3):
                    sc.c_f[i, c] = sc0.c_f[i, c]
            for i in range(holder.shape[0]):
                holder[i] = holder0[i] if i < n_kept else -1
                left_at[i] = left_at0[i] if i < n_kept else math.inf
            _copy(rec0.rec_i, rec_i, n_kept, -1)
            _copy(rec0.rec_f, rec_f, n_kept, math.nan)
            for i in range(n_kept, rec_f.shape[0]):
                rec_f[i, 3] = 0.0
            gs[L.RELEASES] += 1  # parts past n_kept replaced: robots' NooP searches restart
            _retime_noops(p, s, fed, n, n_kept)
            choose_external(p, s, st, sc, picks[j], rule)
            status = run_events(p, s, rec, st, sc, stop_at)
            if status != 0:
                return status
            for i in range(n):
                if lo <= fed[i] and fed[i] < hi and rec_f[i, 1] == rec_f[i, 1]:
                    totals[j] += 1
    return 0


def continue_each(
    line: FastLine,
    futures: Sequence[Future],
    n_kept: int,
    picks: Sequence[int],
    rule: str,
    stop_at: float,
    window: tuple[float, float],
) -> list[int] | None:
    """Grips of parts fed in ``window`` = [lo, hi), summed over ``futures``, for each
    candidate index in ``picks``, when ``line`` (stopped at a decision, ST_CHOOSE) takes that
    candidate and every robot then follows ``rule`` until ``stop_at``.

    ``futures`` are (fed, y[, kind codes]) streams whose first ``n_kept`` parts are the
    line's own. None when a pre-drawn stream ran out (the caller replays those
    continuations instead).
    """
    status, totals, _ = _run(line, futures, n_kept, picks, rule, stop_at, window)
    return None if status else totals.tolist()


def continue_one(
    line: FastLine,
    future: Future,
    n_kept: int,
    pick: int,
    rule: str,
    stop_at: float,
) -> tuple[np.ndarray, np.ndarray]:
    """One continuation's part records (rec_i: robot, rule; rec_f: decided, picked, placed,
    blocked), as :func:`continue_each` plays it: to compare with the SimPy replay."""
    status, _, (rec_i, rec_f) = _run(line, [future], n_kept, [pick], rule, stop_at, (0.0, 0.0))
    if status:
        raise RuntimeError(f"continue_one: the run stopped with status {status}")
    n = len(future[0])
    return rec_i[:n], rec_f[:n]


def _run(
    line: FastLine,
    futures: Sequence[Future],
    n_kept: int,
    picks: Sequence[int],
    rule: str,
    stop_at: float,
    window: tuple[float, float],
) -> tuple[int, np.ndarray, tuple[np.ndarray, np.ndarray]]:
    if int(line.gs[L.STATUS]) != L.ST_CHOOSE:
        raise ValueError("continuations: the line is not stopped at a decision")
    width = max(len(f[0]) for f in futures)
    feds = np.full((len(futures), width), math.inf)
    ys = np.zeros((len(futures), width))
    kinds = np.zeros((len(futures), width), dtype=np.int64)  # (fed, y): one kind, code 0
    for m, future in enumerate(futures):
        f = future[0]
        feds[m, : len(f)] = f
        ys[m, : len(f)] = future[1]
        if len(future) > 2:  # (fed, y, kind codes)
            kinds[m, : len(f)] = future[2]
    lens = np.array([len(f[0]) for f in futures], dtype=np.int64)
    code = L.RULE_NAMES.index(rule)
    p = line.params._replace(ip=line.ip.copy())
    p.ip[:, L.RULE] = code
    totals = np.zeros(len(picks), dtype=np.int64)
    rec_i, rec_f = np.zeros((width, 2), dtype=np.int64), np.zeros((width, 4))
    work = (
        State(
            np.zeros_like(line.fs),
            np.zeros_like(line.ist),
            np.zeros(L.N_GS, dtype=np.int64),
            np.zeros(1),
            np.zeros(width, dtype=np.int64),
            np.zeros(width),
            np.zeros_like(line.counts),
            np.zeros((0, 0), dtype=np.int64),
        ),
        Records(rec_i, rec_f, np.zeros((0, 2), dtype=np.int32), np.zeros((0, 2))),
        Scratch(np.zeros(width + 1, dtype=np.int64), np.zeros((width + 1, 3))),
    )
    at = (line.state, line.records, line.scratch)
    futures_ = (feds, ys, lens, n_kept, kinds)
    asked = np.asarray(picks, dtype=np.int64)
    status = _continue_all(
        p, at, work, line.streams, futures_, asked, code, stop_at, window, totals
    )
    return int(status), totals, (rec_i, rec_f)
