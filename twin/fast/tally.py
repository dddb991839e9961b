"""The KPIs' sums over the engine's record arrays in one compiled pass.

:func:`tally` fills the :class:`twin.kpis.KpiTally` that :func:`twin.kpis.tally` computes
with numpy (about forty array passes) from the same records: the same numbers, each sum
taken in the same order (per robot and column, parts first, then spans, in record order, as
``np.add.at`` takes them), so :func:`twin.kpis.tally_kpis` builds identical KPIs.
"""

from __future__ import annotations

import math

import numpy as np

from pnp_twin.twin.fast.jit import compiled
from pnp_twin.twin.fast.layout import S_NOOP, SPAN_NAMES
from pnp_twin.twin.fast.pool import take
from pnp_twin.twin.fast.structs import Records
from pnp_twin.twin.kpis import PERCENTILES, SPAN_STATES, STATES, WELCH_BINS, KpiTally

COL_OF = np.array(
    [
        *(STATES.index(s) for s in ("wait", "busy", "noop", "blocked", "down", "blocked")),
        STATES.index("busy"),
        STATES.index("blocked"),
    ],
    dtype=np.int64,
)
"""The STATES column of each span state code (an interruption is busy time, holding a part
for an outfeed slot blocked time), then the columns of busy and of blocked time."""
assert SPAN_NAMES == SPAN_STATES  # the engine's span codes are the KPIs'


@compiled(inline=True)
def _clipped(start, end, w0, w1):
    """twin.kpis.clipped for one interval (np.maximum / np.minimum / np.clip, NaN kept)."""
    s = start if (start >= w0 or start != start) else w0
    e = end if (end <= w1 or end != end) else w1
    d = e - s
    return d if (d >= 0.0 or d != d) else 0.0


@compiled()
def _tally(fed, rec, k_spans, window, col_of, out_i, out_f, sums):
    """The sums (see :class:`twin.kpis.KpiTally`) of the parts ``fed`` and their records
    ``rec`` (:class:`~twin.fast.structs.Records`, ``k_spans`` spans) over ``window`` =
    (w0, w1) into zeroed arrays: ``out_i`` rows picks,
    starts, rules, welch_parts, scratch (as long as the parts); ``out_f`` rows states
    (n x 5), welch_picked; ``sums`` the cycles, the cycles by robot, and a spare copy of
    the cycles (as long as the parts; the spare's memory is ``owner``'s, an int64 view of
    it, read before the copy). ``col_of``: :data:`COL_OF`. Returns (presented, picked,
    noops)."""
    rec_i, rec_f, sp_i, sp_f = rec
    w0, w1 = window
    picks, starts, rules, welch_parts, owner = out_i
    states, welch_picked = out_f
    cycles, grouped, spare = sums
    n = picks.shape[0]
    bins = welch_parts.shape[0]
    busy = col_of[-2]
    blocked = col_of[-1]
    presented = 0
    picked = 0
    for i in range(fed.shape[0]):
        f = fed[i]
        got = rec_f[i, 1] == rec_f[i, 1]  # picked: it has a grip time
        if got:
            states[rec_i[i, 0], busy] += _clipped(rec_f[i, 0], rec_f[i, 2], w0, w1)
        if f >= 0.0 and f < w1:
            b = int(f / w1 * bins)
            if b > bins - 1:
                b = bins - 1
            welch_parts[b] += 1
            if got:
                welch_picked[b] += 1.0
        if f >= w0 and f < w1:
            presented += 1
            if got:
                r = rec_i[i, 0]
                cycles[picked] = rec_f[i, 2] - rec_f[i, 0]
                owner[picked] = r
                picked += 1
                picks[r] += 1
                rules[rec_i[i, 1] + 1] += 1
    for r in range(1, n):  # each robot's start (its next slot while filling)
        starts[r] = starts[r - 1] + picks[r - 1]
    for k in range(picked):
        r = owner[k]
        grouped[starts[r]] = cycles[k]
        starts[r] += 1
    for k in range(picked):  # owner is read: its memory takes the spare copy
        spare[k] = cycles[k]
    for r in range(n, 0, -1):  # each robot's next slot is now the next robot's start
        starts[r] = starts[r - 1]
    starts[0] = 0
    noops = 0
    for j in range(k_spans):
        state = sp_i[j, 1]
        start = sp_f[j, 0]
        states[sp_i[j, 0], col_of[state]] += _clipped(start, sp_f[j, 1], w0, w1)
        if state == S_NOOP and start >= w0 and start < w1:
            noops += 1
    if k_spans > 0:  # blocked time sits inside the busy cycle span: move it out of busy
        for r in range(n):
            states[r, busy] -= states[r, blocked]
    return presented, picked, noops


@compiled()
def _select(a, left, right, k):
    """Floyd and Rivest's SELECT: rearrange ``a[left:right + 1]`` (no NaN) so that ``a[k]``
    is its (k - left)-th smallest, the smaller before it, the larger after it; a pivot near
    the k-th is first selected in a sample of the range (in place, recursively)."""
    while right > left:
        if right - left > 600:
            n = right - left + 1
            i = k - left + 1
            z = math.log(n)
            s = 0.5 * math.exp(2.0 * z / 3.0)
            sd = 0.5 * math.sqrt(z * s * (n - s) / n) * (1.0 if i - n / 2.0 >= 0 else -1.0)
            new_left = max(left, int(k - i * s / n + sd))
            new_right = min(right, int(k + (n - i) * s / n + sd))
            _select(a, new_left, new_right, k)
        t = a[k]
        i = left
        j = right
        a[left], a[k] = a[k], a[left]
        if a[right] > t:
            a[right], a[left] = a[left], a[right]
        while i < j:
            a[i], a[j] = a[j], a[i]
            i += 1
            j -= 1
            while a[i] < t:
                i += 1
            while a[j] > t:
                j -= 1
        if a[left] == t:
            a[left], a[j] = a[j], a[left]
        else:
            j += 1
            a[j], a[right] = a[right], a[j]
        if j <= k:
            left = j + 1
        if k <= j:
            right = j - 1


@compiled()
def _order_stats(a, ks):
    """Rearrange ``a`` so that each ``a[k]`` of ``ks`` (ascending, distinct) is the k-th
    smallest of ``a`` (each selected in what lies above the previous k). False (``a``
    untouched) if ``a`` holds a NaN: then let numpy do it."""
    n = a.shape[0]
    for i in range(n):
        if a[i] != a[i]:
            return False
    lo = 0
    for q in range(ks.shape[0]):
        k = ks[q]
        if k == lo:  # the smallest of what is left: one pass
            m = lo
            for i in range(lo + 1, n):
                if a[i] < a[m]:
                    m = i
            a[lo], a[m] = a[m], a[lo]
        else:
            _select(a, lo, n - 1, k)
        lo = k + 1
    return True


BUCKETS = 2048
"""Value buckets of :func:`_kth_values` (a few values each for a run's cycles)."""


@compiled()
def _range(a):
    """(True, its smallest, its largest) of ``a``; False first if it holds a NaN."""
    lo = hi = a[0]
    for i in range(a.shape[0]):
        x = a[i]
        if x != x:
            return False, lo, hi
        if x < lo:
            lo = x
        elif x > hi:
            hi = x
    return True, lo, hi


@compiled(inline=True)
def _bucket(x, lo, scale, top):
    """The bucket of ``x``: ascending with ``x`` (a rounded difference and product are)."""
    return min(int((x - lo) * scale), top)


@compiled()
def _mark(ks, counts, ranks):
    """Negate the count of each bucket that holds one of the ``ks``-th smallest values
    (``ks`` ascending) and write each one's rank among the marked buckets' values."""
    below = 0  # values in the buckets before bucket j
    j = 0
    before = 0  # values in the marked buckets before bucket j
    for q in range(ks.shape[0]):
        while below + abs(counts[j]) <= ks[q]:
            if counts[j] < 0:
                before -= counts[j]
            below += abs(counts[j])
            j += 1
        if counts[j] > 0:
            counts[j] = -counts[j]
        ranks[q] = before + ks[q] - below


@compiled()
def _kth_values(a, ks, counts, ranks, out):
    """``out[q]``: the ``ks[q]``-th smallest value of ``a`` (``ks`` ascending, distinct),
    or False if ``a`` holds a NaN. One pass counts the values per bucket of [min, max],
    another moves those of the buckets holding the ks to the front of ``a``, where
    :func:`_order_stats` selects them: buckets are ascending, so the ks-th smallest are
    those buckets' values of the right ranks (``a`` is reordered)."""
    ok, lo, hi = _range(a)
    if not ok:
        return False
    if not hi - lo < math.inf:  # an infinite value or range: select among them all
        _order_stats(a, ks)
        for q in range(ks.shape[0]):
            out[q] = a[ks[q]]
        return True
    top = counts.shape[0] - 1
    scale = counts.shape[0] / (hi - lo)
    if not scale < math.inf:  # all values equal (or within a few ulps: one bucket then)
        scale = 0.0
    counts[:] = 0
    for i in range(a.shape[0]):
        counts[_bucket(a[i], lo, scale, top)] += 1
    _mark(ks, counts, ranks)
    m = 0
    for i in range(a.shape[0]):
        x = a[i]
        if counts[_bucket(x, lo, scale, top)] < 0:
            a[i] = a[m]
            a[m] = x
            m += 1
    _order_stats(a[:m], ranks)
    for q in range(ks.shape[0]):
        out[q] = a[ranks[q]]
    return True


def linear_percentiles(values: np.ndarray, qs: tuple[float, ...]) -> list[float] | None:
    """``np.percentile(values, qs).tolist()`` (the default linear method), the same doubles,
    from order statistics selected in place (:func:`_kth_values`: ``values`` is
    reordered); None where numpy must do it (a NaN among them)."""
    n = len(values)
    if n == 0:
        return None
    at = [(n - 1) * (q / 100) for q in qs]  # numpy's virtual indexes: (n - 1) * quantile
    wanted = {n - 1 for v in at if v >= n - 1}
    wanted |= {k for v in at if v < n - 1 for k in (math.floor(v), math.floor(v) + 1)}
    ks = np.array(sorted(wanted), dtype=np.int64)
    kth = np.empty(len(ks))
    counts = take("buckets", BUCKETS, np.int64)
    if not _kth_values(values, ks, counts, np.empty(len(ks), np.int64), kth):
        return None
    value = dict(zip(ks.tolist(), kth.tolist(), strict=True))
    out = []
    for v in at:
        if v >= n - 1:  # numpy takes the last value (lerp of it with itself)
            out.append(value[n - 1])
            continue
        prev = math.floor(v)
        t = v - prev
        a, b = value[prev], value[prev + 1]
        diff = b - a  # numpy's _lerp
        out.append(b - diff * (1 - t) if t >= 0.5 else a + diff * t)
    return out


def tally(
    fed: np.ndarray,
    rec: Records,
    n_spans: int,
    n_robots: int,
    n_rules: int,
    warmup: float,
    duration: float,
) -> KpiTally:
    """The :class:`~twin.kpis.KpiTally` of a fast run's arrays over [warmup, duration)
    (``n_rules``: the number of rule codes its picks may carry)."""
    n_parts = len(fed)
    picks, starts, rules = (np.zeros(k, np.int64) for k in (n_robots, n_robots + 1, n_rules + 1))
    welch_parts, welch_picked = np.zeros(WELCH_BINS, np.int64), np.zeros(WELCH_BINS)
    states = np.zeros((n_robots, len(STATES)))
    # scratch the KPIs are read from and never returned: memory earlier runs let go
    cycles, grouped, spare = (take(k, n_parts) for k in ("cycles", "grouped", "spare"))
    owner = spare.view(np.int64)  # scratch, then the spare copy of the cycles
    out_i = (picks, starts, rules, welch_parts, owner)
    out_f = (states, welch_picked)
    window = (warmup, duration)
    presented, picked, noops = _tally(
        fed, rec, n_spans, window, COL_OF, out_i, out_f, (cycles, grouped, spare)
    )
    quantiles = linear_percentiles(spare[:picked], PERCENTILES) if picked else None
    return KpiTally(
        presented=int(presented),
        picked=int(picked),
        picks=picks,
        states=states,
        cycles=cycles[:picked],
        robot_cycles=grouped[:picked],
        robot_starts=starts,
        rules=rules,
        noops=int(noops),
        welch_parts=welch_parts,
        welch_picked=welch_picked,
        spare=spare[:picked],
        percentiles=None if quantiles is None else (quantiles[0], quantiles[1]),
    )
