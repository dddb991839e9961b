"""Confidence intervals: Student's t-interval of a mean, the one copy every layer uses.

The t quantile is computed here with :mod:`math` alone (importing ``scipy.stats`` for it
cost a study about a fifth of its CPU): the t distribution's tail is a regularized incomplete
beta function, evaluated by its continued fraction (Lentz's method), and the quantile is the
root of ``tail(t) = 1 - p``, found by safeguarded Newton steps; one and two degrees of
freedom have closed forms. It agrees with ``scipy.stats.t.ppf`` to 1e-10 (relative above 1)
for 1 to 1000 degrees of freedom (``tests/twin/test_stats.py``). The quantiles of the usual
confidence levels (90, 95 and 99 %, two-sided) for 1 to 1000 degrees of freedom are scipy's
own values (:mod:`twin.t_table`), so every interval is the same double it always was.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from functools import lru_cache

import numpy as np

from pnp_twin.twin.t_table import TABLE

_TINY = 1e-300
_EPS = 1e-16


def _beta_cf(a: float, b: float, x: float) -> float:
    """The continued fraction of the regularized incomplete beta (Numerical Recipes'
    ``betacf``, modified Lentz), for x < (a + 1) / (a + b + 2)."""
    qab, qap, qam = a + b, a + 1.0, a - 1.0
    c, d = 1.0, 1.0 - qab * x / qap
    d = 1.0 / (d if abs(d) > _TINY else _TINY)
    h = d
    for m in range(1, 100_000):
        m2 = 2 * m
        aa = m * (b - m) * x / ((qam + m2) * (a + m2))
        d = 1.0 + aa * d
        d = 1.0 / (d if abs(d) > _TINY else _TINY)
        c = 1.0 + aa / c
        c = c if abs(c) > _TINY else _TINY
        h *= d * c
        aa = -(a + m) * (qab + m) * x / ((a + m2) * (qap + m2))
        d = 1.0 + aa * d
        d = 1.0 / (d if abs(d) > _TINY else _TINY)
        c = 1.0 + aa / c
        c = c if abs(c) > _TINY else _TINY
        step = d * c
        h *= step
        if abs(step - 1.0) < _EPS:
            break
    return h


def _beta_front(a: float, b: float, x: float, y: float) -> float:
    """x^a y^b / (a B(a, b)), with y = 1 - x given separately (no cancellation)."""
    log = math.lgamma(a + b) - math.lgamma(a) - math.lgamma(b) + a * math.log(x) + b * math.log(y)
    return math.exp(log) / a


def _betainc(a: float, b: float, x: float, y: float) -> float:
    """The regularized incomplete beta I_x(a, b); ``y`` is 1 - x."""
    if x <= 0.0:
        return 0.0
    if y <= 0.0:
        return 1.0
    if x < (a + 1.0) / (a + b + 2.0):
        return _beta_front(a, b, x, y) * _beta_cf(a, b, x)
    return 1.0 - _beta_front(b, a, y, x) * _beta_cf(b, a, y)


def t_tail(t: float, df: float) -> float:
    """P(T > t) for Student's t with ``df`` degrees of freedom, ``t >= 0``."""
    t2 = t * t
    return 0.5 * _betainc(df / 2.0, 0.5, df / (df + t2), t2 / (df + t2))


def t_pdf(t: float, df: float) -> float:
    """Student's t density."""
    log = math.lgamma((df + 1.0) / 2.0) - math.lgamma(df / 2.0)
    log -= 0.5 * math.log(df * math.pi) + (df + 1.0) / 2.0 * math.log1p(t * t / df)
    return math.exp(log)


def _upper(q: float, df: float) -> float:
    """The t >= 0 with P(T > t) = q, for 0 < q <= 1/2."""
    if q == 0.5:
        return 0.0
    if df == 1.0:
        return math.tan(math.pi * (0.5 - q))
    if df == 2.0:
        return (1.0 - 2.0 * q) / math.sqrt(2.0 * q * (1.0 - q))
    lo, hi = 0.0, 1.0
    while t_tail(hi, df) > q:  # bracket the root
        lo, hi = hi, 2.0 * hi
    t = 0.5 * (lo + hi)
    for _ in range(200):
        f = t_tail(t, df) - q
        if f > 0.0:
            lo = t
        else:
            hi = t
        step = f / t_pdf(t, df)  # tail' = -pdf: Newton's t - f / tail' = t + step
        new = t + step
        if not lo < new < hi:  # outside the bracket: bisect instead
            new = 0.5 * (lo + hi)
        if abs(new - t) <= 4e-16 * new or hi - lo <= 4e-16 * hi:
            return new
        t = new
    return t


@lru_cache(maxsize=4096)
def _quantile(p: float, df: float) -> float:
    stored = TABLE.get(p)
    if stored is not None and df == int(df) and 1 <= df <= len(stored):
        return stored[int(df) - 1]
    if p > 0.5:
        return _upper(1.0 - p, df)
    return -_upper(p, df)


def t_quantile(p: float, df: float) -> float:
    """Student's t quantile (see the module docstring)."""
    if not 0.0 < p < 1.0:
        raise ValueError(f"p: {p} must be in (0, 1)")
    if not df > 0.0 or math.isinf(df):
        raise ValueError(f"df: {df} must be a positive number")
    return _quantile(float(p), float(df))


def percent_interval(
    values: Sequence[float] | np.ndarray, confidence: float = 0.95
) -> tuple[float, float, float]:
    """:func:`t_interval` of a percentage (G, a value rate): its bounds kept in [0, 100],
    where the figure itself lies (a t-interval over few runs near 100 % reaches above)."""
    mean, low, high = t_interval(values, confidence)
    if math.isnan(low):
        return mean, low, high
    return mean, max(low, 0.0), min(high, 100.0)


def t_interval(
    values: Sequence[float] | np.ndarray, confidence: float = 0.95
) -> tuple[float, float, float]:
    """(mean, low, high): the t-interval of the mean; NaN bounds below two values."""
    x = np.asarray(values, dtype=float)
    x = x[~np.isnan(x)]
    n = len(x)
    if n == 0:
        return math.nan, math.nan, math.nan
    mean = float(x.mean())
    if n < 2:
        return mean, math.nan, math.nan
    half = t_quantile(0.5 + confidence / 2.0, n - 1) * float(x.std(ddof=1)) / math.sqrt(n)
    return mean, mean - half, mean + half
