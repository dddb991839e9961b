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
"""

from __future__ import annotations

import math

import numpy as np
from numba import prange

from pnp_twin.twin.fast.gateway import release
from pnp_twin.twin.fast.jit import compiled
from pnp_twin.twin.fast.kernel import run_events
from pnp_twin.twin.fast.layout import CLAIMED, LASTCLAIM, NOOP, NOW, PENDING, RULE, ST_EPOCH, STATUS
from pnp_twin.twin.fast.robot import _candidates, start_robots

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


@compiled()
def _observe(obs, fed, ys, holder, left_at, ist, spans, ef, now):
    """BeltCamera._draw then .belt: parts, claimed parts, busy robots' workspace columns."""
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


@compiled()
def _collect(ist, holder, counts, started, noops0, picks, noops, rewards, options, ef, now):
    """EpochDriver._collect: picks of the options running, then the options that ended for
    the robots deciding now; adds picks, NooPs and eq. 1 + eq. 2 per robot."""
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


@compiled()
def _choices(fp, fs, ist, gp, fed, ys, holder, now, c_i, c_f, cand):
    """Each deciding robot's candidate parts now (0 for the others); True if any has one."""
    any_choice = False
    for r in range(ist.shape[0]):
        cand[r] = 0
        if ist[r, PENDING]:
            cand[r] = _candidates(fp, fs, ist, gp, fed, ys, holder, now, r, c_i, c_f)
            if cand[r] > 0:
                any_choice = True
    return any_choice


@compiled()
def _act(ip, fs, ist, gs, gf, counts, codes, started, noops0, keep):
    """EpochDriver.act: the deciding robots' rules set (kept with ``keep``), their options
    opened, released."""
    now = gf[NOW]
    for r in range(ist.shape[0]):
        if ist[r, PENDING]:
            if not keep:
                ip[r, RULE] = codes[r]
            ist[r, LASTCLAIM] = -1
            started[r] = now
            noops0[r] = counts[r, NOOP]
    release(fs, ist, gs, now)


@compiled()
def _restart(ip0, ip, fs, ist, gs, gf, fed, holder, left_at, counts, started, noops0, epi, ef):
    """A fresh line (its parts and pre-drawn streams already in place): state at t = 0."""
    for r in range(ip.shape[0]):  # a loop: copying an array in place would allocate
        for j in range(ip.shape[1]):
            ip[r, j] = ip0[r, j]
    fs[:] = 0.0
    ist[:] = 0
    gs[:] = 0
    gf[:] = 0.0
    counts[:] = 0
    holder[:] = -1
    left_at[:] = math.inf
    started[:] = math.nan
    noops0[:] = 0
    epi[:] = 0
    first = np.searchsorted(fed, ef[WARMUP], side="left")
    epi[FIRST] = first
    epi[PASSED] = first


@compiled(parallel=True)
def step_lines(
    fp, ip0, gp, gi, ef, ei, spans, ip, fs, ist, gs, gf, fed, ys, holder, left_at, counts,
    siro, exps, rec_i, rec_f, sp_i, sp_f, c_i, c_f, codes, mode, started, noops0, epi,
    obs, reward, term, trunc, tau, grip, picks, noops, rewards, options, cand, skipped,
):  # fmt: skip
    """Step every line as ``mode[e]`` says: RESET starts line e afresh (reward 0, not
    ended), ACT gives its pending robots the rule codes ``codes[e]``; both then run it to
    its next decision epoch (with ``ei[SKIP_NOOPS]``, on past epochs where no deciding
    robot has a candidate, the robots keeping their rules). SKIP leaves it as it is."""
    n_env = fs.shape[0]
    n_chunks = c_i.shape[0]
    for k in prange(n_chunks):
        for e in range(k * n_env // n_chunks, (k + 1) * n_env // n_chunks):
            if mode[e] == SKIP:
                continue
            before = gf[e, NOW]
            fresh = mode[e] == RESET
            if fresh:
                _restart(
                    ip0, ip[e], fs[e], ist[e], gs[e], gf[e], fed[e], holder[e], left_at[e],
                    counts[e], started[e], noops0[e], epi[e], ef,
                )  # fmt: skip
                start_robots(fp, ip[e], fs[e], ist[e], gs[e], exps[e])
                before = 0.0
            else:
                _act(
                    ip[e], fs[e], ist[e], gs[e], gf[e], counts[e], codes[e], started[e],
                    noops0[e], False,
                )  # fmt: skip
                epi[e, STEPS] += 1
            picks[e, :] = 0
            noops[e, :] = 0
            rewards[e, :] = 0.0
            skipped[e] = 0
            while True:
                run_events(
                    fp, ip[e], gp, gi, fs[e], ist[e], gs[e], gf[e], fed[e], ys[e], holder[e],
                    left_at[e], rec_i[k], rec_f[k], sp_i[k], sp_f[k], counts[e], siro[e],
                    exps[e], c_i[k], c_f[k], math.inf,
                )  # fmt: skip
                now = gf[e, NOW]
                _collect(
                    ist[e], holder[e], counts[e], started[e], noops0[e], picks[e], noops[e],
                    rewards[e], options[e], ef, now,
                )  # fmt: skip
                choice = _choices(
                    fp, fs[e], ist[e], gp, fed[e], ys[e], holder[e], now, c_i[k], c_f[k],
                    cand[e],
                )  # fmt: skip
                if gs[e, STATUS] != ST_EPOCH or not ei[SKIP_NOOPS] or choice:
                    break
                if now >= ef[DURATION] or now >= ef[MAX_TIME]:
                    break
                _act(
                    ip[e], fs[e], ist[e], gs[e], gf[e], counts[e], codes[e], started[e],
                    noops0[e], True,
                )  # fmt: skip
                skipped[e] += 1
            _close(
                ef, ei, spans, ist[e], gf[e], fed[e], ys[e], holder[e], left_at[e], epi[e],
                obs[e], rewards[e], fresh, reward, term, trunc, tau, grip, e, before,
            )  # fmt: skip


@compiled()
def _close(
    ef, ei, spans, ist, gf, fed, ys, holder, left_at, epi, obs, rewards, fresh, reward, term,
    trunc, tau, grip, e, before,
):  # fmt: skip
    """The step's results for line e at its new epoch (PickPlaceEnv.step and _get_info)."""
    now = gf[NOW]
    done = now >= ef[DURATION]
    capped = (ei[MAX_STEPS] > 0 and epi[STEPS] >= ei[MAX_STEPS]) or now >= ef[MAX_TIME]
    total = 0.0
    for r in range(rewards.shape[0]):
        total += rewards[r]
    reward[e] = 0.0 if fresh else total
    term[e] = done and not fresh
    trunc[e] = capped and not done and not fresh
    tau[e] = now - before
    grip[e] = _gripping_rate(fed, holder, epi, ef, now)
    _observe(obs, fed, ys, holder, left_at, ist, spans, ef, now)


def statuses_ok(gs: np.ndarray) -> bool:
    """True when every line stopped at its next decision epoch (no stream ran out)."""
    return bool((gs[:, STATUS] == ST_EPOCH).all())
