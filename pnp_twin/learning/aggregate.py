"""Aggregates over training runs, as marl-eval and rliable report them.

A baseline trained with several seeds on several tasks gives one score per (task, training
run): here its gain in G over the task's best rule on the task's evaluation seeds, in
points, and that gain as a share of the planner bound's gain on the task (``normalized``:
0 = the best rule, 1 = the clairvoyant one-step bound). :func:`aggregate` reports over all
(task, run) scores the **interquartile mean** (the mean of the middle half: robust to one
run that diverged or got lucky, unlike the mean, and less noisy than the median) and the
mean, each with a 95 % **stratified bootstrap** interval: runs resampled with replacement
within each task, the statistic recomputed on each resample, the percentile interval
(Agarwal et al. 2021, "Deep RL at the edge of the statistical precipice"; marl-eval's
protocol, Gorsane et al. 2022). The interval is over training runs: it says how much a
result would move with other training seeds, which per-seed evaluation intervals do not.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from scipy.stats import trim_mean


def iqm(values: Sequence[float] | np.ndarray) -> float:
    """The interquartile mean: the mean of ``values`` with the lowest and highest quarter
    cut (``floor(n / 4)`` values each end), as rliable computes it (scipy's ``trim_mean``)."""
    x = np.asarray(values, dtype=np.float64).ravel()
    if len(x) == 0:
        raise ValueError("iqm: no values")
    return float(trim_mean(x, 0.25))


def normalized(gain: float, bound_gain: float) -> float:
    """A gain over the best rule as a share of the bound's gain on the same task."""
    return gain / bound_gain if bound_gain > 0 else float("nan")


def aggregate(
    scores: Mapping[str, Sequence[float]],
    resamples: int = 2000,
    confidence: float = 0.95,
    seed: int = 0,
) -> dict[str, Any]:
    """IQM and mean over every (task, run) score in ``scores`` (task -> one score per
    training run), each with its stratified bootstrap percentile interval."""
    tasks = {t: np.asarray(v, dtype=np.float64) for t, v in scores.items() if len(v)}
    if not tasks:
        raise ValueError("aggregate: no scores")
    every = np.concatenate(list(tasks.values()))
    rng = np.random.default_rng(seed)
    boot = np.empty((resamples, 2))
    for b in range(resamples):
        sample = np.concatenate([v[rng.integers(0, len(v), len(v))] for v in tasks.values()])
        boot[b] = iqm(sample), sample.mean()
    tail = 100 * (1 - confidence) / 2
    lo, hi = np.percentile(boot, [tail, 100 - tail], axis=0)
    return {
        "iqm": iqm(every),
        "iqm_ci": [float(lo[0]), float(hi[0])],
        "mean": float(every.mean()),
        "mean_ci": [float(lo[1]), float(hi[1])],
        "runs": int(len(every)),
        "tasks": len(tasks),
        "resamples": resamples,
    }


__all__ = ["aggregate", "iqm", "normalized"]
