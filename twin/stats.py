"""Confidence intervals: Student's t-interval of a mean, the one copy every layer uses.

scipy is imported on first use, so importing the core stays light.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np


def t_quantile(p: float, df: float) -> float:
    """Student's t quantile."""
    if not 0.0 < p < 1.0:
        raise ValueError(f"p: {p} must be in (0, 1)")
    from scipy import stats

    return float(stats.t.ppf(p, df))


def t_interval(values: Sequence[float], confidence: float = 0.95) -> tuple[float, float, float]:
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
