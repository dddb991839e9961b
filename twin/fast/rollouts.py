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


@compiled()
def _retime_noops(fp, gp, fs, ist, fed, n, n_kept):
    """NooPs timed by a part index >= n_kept (or by none) wait for this stream's next part."""
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
def _continue_all(
    fp, ip, gp, gi, fs0, ist0, gs0, gf0, holder0, left_at0, rec_i0, rec_f0, counts0,
    c_i0, c_f0, siro, exps, feds, ys, lens, n_kept, picks, rule, stop_at, lo, hi,
    fs, ist, gs, gf, holder, left_at, rec_i, rec_f, counts, c_i, c_f, sp_i, sp_f, totals,
):  # fmt: skip
    """Every (future, pick) continuation; totals[p] sums the window's grips over futures.

    ``feds``/``ys`` hold one future per row, padded with fed = inf past ``lens[m]`` (the
    kernel sees no part there); the scratch arrays have one row per padded part."""
    for m in range(feds.shape[0]):
        n = lens[m]
        fed = feds[m]
        for p in range(picks.shape[0]):
            _copy(fs0, fs, fs.shape[0], 0.0)
            _copy(ist0, ist, ist.shape[0], 0)
            _copy(counts0, counts, counts.shape[0], 0)
            for i in range(gs.shape[0]):
                gs[i] = gs0[i]
            gf[0] = gf0[0]
            for i in range(gs0[L.DN]):  # the decision's candidates (the rest is scratch)
                c_i[i] = c_i0[i]
                for c in range(3):
                    c_f[i, c] = c_f0[i, c]
            for i in range(holder.shape[0]):
                holder[i] = holder0[i] if i < n_kept else -1
                left_at[i] = left_at0[i] if i < n_kept else math.inf
            _copy(rec_i0, rec_i, n_kept, -1)
            _copy(rec_f0, rec_f, n_kept, math.nan)
            for i in range(n_kept, rec_f.shape[0]):
                rec_f[i, 3] = 0.0
            gs[L.RELEASES] += 1  # parts past n_kept replaced: robots' NooP searches restart
            _retime_noops(fp, gp, fs, ist, fed, n, n_kept)
            choose_external(fp, gp, fs, ist, gs, holder, left_at, c_i, c_f, picks[p], rule)
            status = run_events(
                fp, ip, gp, gi, fs, ist, gs, gf, fed, ys[m], holder, left_at, rec_i, rec_f,
                sp_i, sp_f, counts, siro, exps, c_i, c_f, stop_at,
            )  # fmt: skip
            if status != 0:
                return status
            for i in range(n):
                if lo <= fed[i] and fed[i] < hi and rec_f[i, 1] == rec_f[i, 1]:
                    totals[p] += 1
    return 0


def continue_each(
    line: FastLine,
    futures: Sequence[tuple[np.ndarray, np.ndarray]],
    n_kept: int,
    picks: Sequence[int],
    rule: str,
    stop_at: float,
    window: tuple[float, float],
) -> list[int] | None:
    """Grips of parts fed in ``window`` = [lo, hi), summed over ``futures``, for each
    candidate index in ``picks``, when ``line`` (stopped at a decision, ST_CHOOSE) takes that
    candidate and every robot then follows ``rule`` until ``stop_at``.

    ``futures`` are (fed, y) streams whose first ``n_kept`` parts are the line's own. None
    when a pre-drawn stream ran out (the caller replays those continuations instead).
    """
    status, totals, _ = _run(line, futures, n_kept, picks, rule, stop_at, window)
    return None if status else totals.tolist()


def continue_one(
    line: FastLine,
    future: tuple[np.ndarray, np.ndarray],
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
    futures: Sequence[tuple[np.ndarray, np.ndarray]],
    n_kept: int,
    picks: Sequence[int],
    rule: str,
    stop_at: float,
    window: tuple[float, float],
) -> tuple[int, np.ndarray, tuple[np.ndarray, np.ndarray]]:
    if int(line.gs[L.STATUS]) != L.ST_CHOOSE:
        raise ValueError("continuations: the line is not stopped at a decision")
    n_rob = len(line.specs)
    width = max(len(f) for f, _ in futures)
    feds = np.full((len(futures), width), math.inf)
    ys = np.zeros((len(futures), width))
    for m, (f, y) in enumerate(futures):
        feds[m, : len(f)] = f
        ys[m, : len(f)] = y
    lens = np.array([len(f) for f, _ in futures], dtype=np.int64)
    code = L.RULE_NAMES.index(rule)
    ip = line.ip.copy()
    ip[:, L.RULE] = code
    totals = np.zeros(len(picks), dtype=np.int64)
    rec_i, rec_f = np.zeros((width, 2), dtype=np.int64), np.zeros((width, 4))
    status = _continue_all(
        line.fp, ip, line.gp, line.gi, line.fs, line.ist, line.gs, line.gf, line.holder,
        line.left_at, line.rec_i, line.rec_f, line.counts, line._c_i, line._c_f, line._siro,
        line._exps, feds, ys, lens, n_kept, np.asarray(picks, dtype=np.int64), code, stop_at,
        window[0], window[1], np.zeros((n_rob, L.N_FS)), np.zeros((n_rob, L.N_IS), np.int64),
        np.zeros(L.N_GS, dtype=np.int64), np.zeros(1), np.zeros(width, dtype=np.int64),
        np.zeros(width), rec_i, rec_f, np.zeros_like(line.counts),
        np.zeros(width + 1, dtype=np.int64), np.zeros((width + 1, 3)),
        np.zeros((0, 2), dtype=np.int32), np.zeros((0, 2)), totals,
    )  # fmt: skip
    return int(status), totals, (rec_i, rec_f)
