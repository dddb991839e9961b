"""The fast engine's reused buffers (twin.fast.pool) and its percentiles (twin.fast.tally)."""

from __future__ import annotations

import numpy as np

from pnp_twin.twin.fast.pool import take
from pnp_twin.twin.fast.tally import linear_percentiles


def _addr(a: np.ndarray) -> int:
    return int(a.__array_interface__["data"][0])


def test_a_buffer_is_reused_only_when_nothing_refers_to_it() -> None:
    a = take("test-role", (10, 2))
    b = take("test-role", (10, 2))
    assert not np.shares_memory(a, b)  # a is alive: b is new
    at = _addr(b)
    del a, b
    c = take("test-role", (8, 2), np.float64)
    assert _addr(c) == at and c.shape == (8, 2)  # b's memory, let go
    view = c[2:]
    del c
    d = take("test-role", (8, 2))
    assert _addr(d) != at and _addr(view) == at + 2 * 2 * 8  # a view keeps it
    e = take("test-role", 4, np.int64)  # another dtype: new
    assert e.dtype == np.int64 and e.shape == (4,)


def test_the_percentiles_are_numpys() -> None:
    rng = np.random.default_rng(5)
    for trial in range(3000):
        n = int(rng.integers(1, 60)) if trial % 10 else int(rng.integers(1, 20000))
        kind = trial % 6
        if kind == 0:
            x = rng.normal(size=n)
        elif kind == 1:
            x = rng.integers(0, 5, n).astype(float)  # ties
        elif kind == 2:
            x = np.sort(rng.gamma(2.0, 1.0, n))[:: 1 if trial % 8 < 4 else -1].copy()
        elif kind == 3:
            x = np.full(n, 1.5)
        elif kind == 4:  # a few ulps apart: one value bucket
            x = 1.0 + rng.integers(0, 3, n) * 2.0**-52
        else:  # heavy tails: most values in a few buckets
            x = rng.exponential(size=n) ** 6
        want = np.percentile(x, (50, 95)).tolist()
        y = x.copy()
        assert linear_percentiles(y, (50, 95)) == want
        assert sorted(y.tolist()) == sorted(x.tolist())  # reordered, the same values
    for big in (np.inf, 1e308):  # an infinite value, an infinite range
        x = rng.normal(size=1000)
        x[[5, 700]] = big, -big
        want = np.percentile(x, (50, 95)).tolist()
        got = linear_percentiles(x.copy(), (50, 95))
        assert got == want
    x = rng.normal(size=100)
    x[3] = np.nan
    assert linear_percentiles(x, (50, 95)) is None  # numpy's, then
    assert linear_percentiles(np.zeros(0), (50, 95)) is None
