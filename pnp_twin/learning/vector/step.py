"""Many lines in hold mode stepped in one compiled call: the vector environment's step.

Every per-run array of :class:`~pnp_twin.twin.fast.engine.FastLine` gets a leading env axis
(parts padded to a common length with ``fed = inf``, which the kernel's bisections and
``_next_entry`` read as "no part"). One :func:`step_lines` call answers each line's pending
decision epoch with its robots' rule codes (or starts the line afresh), runs it to its next
epoch with the kernel's ``run_events``, keeps the epoch driver's option bookkeeping
(:class:`pnp_twin.learning.envs.driver.EpochDriver`: claims, picks, NooPs, eq. 1 + eq. 2
rewards per robot), counts each deciding robot's candidate parts (the action masks), skips
epochs where no robot has a choice when asked (``skip_noops``), the episode's end, the
gripping rate over the command line's window, and writes the observation
(``BeltCamera._draw``, bit for bit) into one preallocated uint8 array.

Lines are split into chunks; chunks run on numba's threads (``prange``), each with its own
scratch arrays (candidates, and the pick records the kernel writes but no environment reads).

The arrays travel in the kernel's structures (:mod:`pnp_twin.twin.fast.structs`) with a
leading line (or chunk) axis, and in three of this module's: :class:`EnvParams`,
:class:`Episodes` and :class:`StepOut`.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import prange

from pnp_twin.twin.fast.gateway import release
from pnp_twin.twin.fast.jit import compiled
from pnp_twin.twin.fast.kernel import run_events
from pnp_twin.twin.fast.layout import CLAIMED, LASTCLAIM, NOOP, NOW, PENDING, RULE, ST_EPOCH, STATUS
from pnp_twin.twin.fast.robot import _candidates, start_robots
from pnp_twin.twin.fast.structs import (
    params_of,
    records_of,
    scratch_of,
    state_of,
    streams_of,
)

# env float parameters ef[.]
DURATION, MAX_TIME, W_EXT, W_INT, PENALTY, BELT_LAG, END_LAG, COL_SCALE, ROW_SCALE, SPEED = range(
    10
)
WARMUP = 10
N_EF = 11
# env int parameters ei[.]: the step cap (0: none), skip forced NooPs (0/1)
MAX_STEPS, SKIP_NOOPS = range(2)
N_EI = 2
# episode state epi[e, .]: decision steps so far, parts passed, of them picked (gripping
# rate), the first part fed at or after the warm-up
STEPS, PASSED, PASSED_PICKED, FIRST = range(4)
N_EPI = 4
# what a step does to each line: nothing, answer its epoch, or start it afresh
SKIP, ACT, RESET = range(3)


class EnvParams(NamedTuple):
    """What every line's episode reads."""

    ef: np.ndarray  # float64 (N_EF,): see the column names above
    ei: np.ndarray  # int64 (N_EI,): step cap, skip forced NooPs
    spans: np.ndarray  # int64 (robots, 2): each workspace's columns in the image
    ip0: np.ndarray  # int64 (robots, N_IP): a fresh line's robot int parameters


class Episodes(NamedTuple):
    """Each line's option bookkeeping and episode state (a leading line axis)."""

    started: np.ndarray  # float64 (lines, robots): when each robot's option began
    noops0: np.ndarray  # int64 (lines, robots): its NooP count then
    epi: np.ndarray  # int64 (lines, N_EPI): see the column names above


class StepOut(NamedTuple):
    """What a step returns for each line (a leading line axis)."""

    obs: np.ndarray  # uint8 (lines, channels, rows, columns): the camera image
    reward: np.ndarray  # float64 (lines,)
    term: np.ndarray  # bool (lines,)
    trunc: np.ndarray  # bool (lines,)
    tau: np.ndarray  # float64 (lines,): the step's duration
    grip: np.ndarray  # float64 (lines,): gripping rate, percent
    picks: np.ndarray  # int64 (lines, robots)
    noops: np.ndarray  # int64 (lines, robots)
    rewards: np.ndarray  # float64 (lines, robots): eq. 1 + eq. 2
    options: np.ndarray  # float64 (lines, robots): durations of the options that ended
    cand: np.ndarray  # int64 (lines, robots): each deciding robot's candidates
    skipped: np.ndarray  # int64 (lines,): epochs skipped (no deciding robot had a choice)


@compiled()
def _observe(obs, s, st, env, now):
    """BeltCamera._draw then .belt: parts, claimed parts, busy robots' workspace columns."""
    fed, ys, holder, left_at, ist = st.fed, st.ys, s.holder, s.left_at, s.ist
    ef, spans = env.ef, env.spans
    c, ny, nx = obs.shape
    obs[:] = 0
    lo = np.searchsorted(fed, now - ef[BELT_LAG], side="left")
    hi = np.searchsorted(fed, now, side="right")
    v, scale, rscale, last = ef[SPEED], ef[COL_SCALE], ef[ROW_SCALE], nx - 1
    for i in range(lo, hi):
        if left_at[i] > now:  # not gripped yet
            col = int(v * (now - fed[i]) * scale)
            if col > last:
                col = last
            row = int(ys[i] * rscale)
            if row > ny - 1:
                row = ny - 1
            obs[0, row, col] = 1
            if c > 1 and holder[i] >= 0:
                obs[1, row, col] = 1
    if c > 2:
        for r in range(ist.shape[0]):
            if not ist[r, PENDING]:
                obs[2, :, spans[r, 0] : spans[r, 1]] = 1


@compiled()
def _gripping_rate(fed, holder, epi, ef, now):
    """EpochDriver.gripping_rate: percent picked of the parts fed at or after the warm-up
    that have passed the last workspace."""
    n = np.searchsorted(fed, now - ef[END_LAG], side="right")
    picked = epi[PASSED_PICKED]
    for i in range(epi[PASSED], n):
        if holder[i] >= 0:
            picked += 1
    if n > epi[PASSED]:
        epi[PASSED] = n
        epi[PASSED_PICKED] = picked
    seen = epi[PASSED] - epi[FIRST]
    return 100.0 * picked / seen if seen > 0 else 0.0


@compiled(inline=True)
def _collect(s, ep, out, e, ef, now):
    """EpochDriver._collect for line e: picks of the options running, then the options that
    ended for the robots deciding now; adds picks, NooPs and eq. 1 + eq. 2 per robot."""
    ist, holder, counts = s.ist, s.holder, s.counts
    started, noops0 = ep.started[e], ep.noops0[e]
    picks, noops, rewards, options = out.picks[e], out.noops[e], out.rewards[e], out.options[e]
    for r in range(ist.shape[0]):
        part = ist[r, LASTCLAIM]
        if part >= 0 and ist[r, CLAIMED] == -1 and holder[part] == r:  # gripped
            picks[r] += 1
            ist[r, LASTCLAIM] = -2  # this option picked its part
    for r in range(ist.shape[0]):
        options[r] = 0.0
        start = started[r]
        if not ist[r, PENDING] or start != start:  # not deciding, or the first epoch
            continue
        duration = now - start
        options[r] = duration
        ext = 0.0
        if ist[r, LASTCLAIM] == -2 and duration > 0.0:
            ext = 1 / duration
        intr = 0.0
        if counts[r, NOOP] > noops0[r]:
            intr = -ef[PENALTY]
            noops[r] += 1
        rewards[r] += ef[W_EXT] * ext + ef[W_INT] * intr


@compiled(inline=True)
def _choices(p, s, st, sc, now, cand):
    """Each deciding robot's candidate parts now (0 for the others); True if any has one."""
    ist = s.ist
    any_choice = False
    for r in range(ist.shape[0]):
        cand[r] = 0
        if ist[r, PENDING]:
            cand[r] = _candidates(p, s, st, sc, r, now)
            if cand[r] > 0:
                any_choice = True
    return any_choice


@compiled(inline=True)
def _act(p, s, ep, e, codes, keep):
    """EpochDriver.act for line e: the deciding robots' rules set to ``codes`` (kept with
    ``keep``), their options opened, released."""
    ist, started, noops0 = s.ist, ep.started[e], ep.noops0[e]
    now = s.gf[NOW]
    for r in range(ist.shape[0]):
        if ist[r, PENDING]:
            if not keep:
                p.ip[r, RULE] = codes[r]
            ist[r, LASTCLAIM] = -1
            started[r] = now
            noops0[r] = s.counts[r, NOOP]
    release(s)


@compiled()
def _restart(p, s, st, ep, e, env):
    """A fresh line e (its parts and pre-drawn streams already in place): state at t = 0."""
    ip, ip0 = p.ip, env.ip0
    for r in range(ip.shape[0]):  # a loop: copying an array in place would allocate
        for j in range(ip.shape[1]):
            ip[r, j] = ip0[r, j]
    s.fs[:] = 0.0
    s.ist[:] = 0
    s.gs[:] = 0
    s.gf[:] = 0.0
    s.counts[:] = 0
    s.holder[:] = -1
    s.left_at[:] = math.inf
    ep.started[e, :] = math.nan
    ep.noops0[e, :] = 0
    epi = ep.epi[e]
    epi[:] = 0
    first = np.searchsorted(st.fed, env.ef[WARMUP], side="left")
    epi[FIRST] = first
    epi[PASSED] = first


@compiled(parallel=True)
def step_lines(p, env, lines, streams, recs, scratch, episodes, out, codes, mode):
    """Step every line as ``mode[e]`` says: RESET starts line e afresh (reward 0, not
    ended), ACT gives its pending robots the rule codes ``codes[e]``; both then run it to
    its next decision epoch (with ``ei[SKIP_NOOPS]``, on past epochs where no deciding
    robot has a candidate, the robots keeping their rules). SKIP leaves it as it is.

    ``p``: the lines' :class:`~pnp_twin.twin.fast.structs.Params` with a rule code row
    per line (``ip``: lines x robots x N_IP); ``lines``, ``streams``: their states and
    streams; ``recs``, ``scratch``: one row per chunk of lines."""
    n_env = lines.fs.shape[0]
    n_chunks = scratch.c_i.shape[0]
    for k in prange(n_chunks):
        lo, hi = k * n_env // n_chunks, (k + 1) * n_env // n_chunks
        rec, sc = records_of(recs, k), scratch_of(scratch, k)
        _step_chunk(p, env, lines, streams, rec, sc, episodes, out, codes, mode, lo, hi)


@compiled()
def _step_chunk(p, env, lines, streams, rec, sc, episodes, out, codes, mode, lo, hi):
    """Lines lo to hi - 1 (one chunk) stepped as :func:`step_lines` says, in a function
    of its own because numba's parallel loop loses writes made through a structure's
    attribute inside it (``out.rewards[e, :] = 0.0`` had no effect there, numba 0.68).
    One call per chunk, not per line: a call passes every array of its structures as
    separate arguments (some 360 for these)."""
    for e in range(lo, hi):
        if mode[e] != SKIP:
            _step_line(p, env, lines, streams, rec, sc, episodes, out, codes[e], mode[e], e)


@compiled(inline=True)
def _step_line(p, env, lines, streams, rec, sc, episodes, out, codes, mode, e):
    """Line e's step (see :func:`step_lines`), inlined in :func:`_step_chunk`, as are the
    helpers it calls with the batch's whole structures (``_act``, ``_collect``,
    ``_close``)."""
    ef, ei = env.ef, env.ei
    pe = params_of(p, p.ip, e)
    s = state_of(lines, e)
    st = streams_of(streams, e)
    before = s.gf[NOW]
    fresh = mode == RESET
    if fresh:
        _restart(pe, s, st, episodes, e, env)
        start_robots(pe, s, st)
        before = 0.0
    else:
        _act(pe, s, episodes, e, codes, False)
        episodes.epi[e, STEPS] += 1
    out.picks[e, :] = 0
    out.noops[e, :] = 0
    out.rewards[e, :] = 0.0
    out.skipped[e] = 0
    while True:
        run_events(pe, s, rec, st, sc, math.inf)
        now = s.gf[NOW]
        _collect(s, episodes, out, e, ef, now)
        choice = _choices(pe, s, st, sc, now, out.cand[e])
        if s.gs[STATUS] != ST_EPOCH or not ei[SKIP_NOOPS] or choice:
            break
        if now >= ef[DURATION] or now >= ef[MAX_TIME]:
            break
        _act(pe, s, episodes, e, codes, True)
        out.skipped[e] += 1
    _close(env, s, st, episodes.epi[e], out, e, fresh, before)


@compiled(inline=True)
def _close(env, s, st, epi, out, e, fresh, before):
    """The step's results for line e at its new epoch (PickPlaceEnv.step and _get_info)."""
    ef, ei = env.ef, env.ei
    now = s.gf[NOW]
    done = now >= ef[DURATION]
    capped = (ei[MAX_STEPS] > 0 and epi[STEPS] >= ei[MAX_STEPS]) or now >= ef[MAX_TIME]
    total = 0.0
    rewards = out.rewards[e]
    for r in range(rewards.shape[0]):
        total += rewards[r]
    out.reward[e] = 0.0 if fresh else total
    out.term[e] = done and not fresh
    out.trunc[e] = capped and not done and not fresh
    out.tau[e] = now - before
    out.grip[e] = _gripping_rate(st.fed, s.holder, epi, ef, now)
    _observe(out.obs[e], s, st, env, now)


def statuses_ok(gs: np.ndarray) -> bool:
    """True when every line stopped at its next decision epoch (no stream ran out)."""
    return bool((gs[:, STATUS] == ST_EPOCH).all())
