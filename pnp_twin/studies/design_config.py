"""One configuration of a design: its values, rule, price and runs, at every condition.

A configuration is bought once and must meet the target at each condition it will see
(``--across``: flows, shifts' traces); each condition is a :class:`Cell` with its own runs
(common random numbers: replication k has the same seed in every cell). Its interval of G
is the worst cell's: with every cell's interval holding together, the lowest lower bound and
the lowest upper bound bound the lowest G. Lost parts (the running cost) are averaged over
the conditions, each weighted equally. Without ``--across`` there is one cell, the line
itself, and every figure is what it was before conditions existed.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

from pnp_twin.studies.prices import SECONDS_PER_HOUR, running_per_part
from pnp_twin.twin.scenario import Scenario
from pnp_twin.twin.stats import t_interval


class Cell:
    """One configuration at one condition: its scenario and runs so far."""

    def __init__(self, condition: dict[str, Any], scenario: Scenario) -> None:
        self.condition = condition
        self.scenario = scenario
        self.g: list[float] = []  # the gripping rate per replication (the lost parts' cost)
        self.y: list[float] = []  # the figure the target is on (--kpi; G by default)
        self.flow: list[float] = []
        self._bounds: dict[tuple[float, int], tuple[float, float, float]] = {}

    def bounds(self, level: float) -> tuple[float, float, float]:
        # kept per count of runs (runs are only ever appended): a design asks every
        # configuration's bounds at each point, thousands of times over
        key = (level, len(self.y))
        if key not in self._bounds:
            mean, low, high = t_interval(self.y, level)
            low = max(low, 0.0) if math.isfinite(low) else 0.0
            high = min(high, 100.0) if math.isfinite(high) else 100.0
            self._bounds[key] = mean, low, high
        return self._bounds[key]

    def lost_per_s(self) -> float:
        """Parts lost per second, from the mean flow and the mean G."""
        mean_g = sum(self.g) / len(self.g)
        flow = sum(self.flow) / len(self.flow)
        return flow * (1.0 - mean_g / 100.0)

    def lost_half_width(self, confidence: float) -> float:
        """The half-width of the t-interval of the lost parts per second (per replication:
        flow x (1 - G)); 0 with one replication's worth of nothing to go on."""
        each = [f * (1.0 - g / 100.0) for f, g in zip(self.flow, self.g, strict=True)]
        mean, low, high = t_interval(each, confidence)
        return (high - low) / 2 if math.isfinite(high - low) else math.inf

    def gripped_per_s(self) -> float:
        return sum(f * g / 100.0 for f, g in zip(self.flow, self.g, strict=True)) / len(self.g)


class Config:
    """One configuration: its values, rule, price, and one cell per condition."""

    def __init__(
        self,
        values: dict[str, Any],
        policy: str,
        cells: Sequence[Cell],
        cost: float,
        prices: Sequence[float] = (),
    ) -> None:
        self.values = values
        self.policy = policy
        self.cells = list(cells)
        self.capital = cost
        self.prices = list(prices)  # each robot's price, robot 1 first (owned ones 0)

    @property
    def scenario(self) -> Scenario:
        """The line as bought (at the first condition)."""
        return self.cells[0].scenario

    @property
    def g(self) -> list[float]:
        """The first cell's runs: as many as every cell has."""
        return self.cells[0].g

    def label(self) -> str:
        return ", ".join(f"{k}={v}" for k, v in self.values.items()) + f", {self.policy}"

    def bounds(self, level: float) -> tuple[float, float, float]:
        """The worst condition's G: the lowest mean, lower bound and upper bound."""
        each = [c.bounds(level) for c in self.cells]
        return min(b[0] for b in each), min(b[1] for b in each), min(b[2] for b in each)

    def lost_cost(self, costs: Mapping[str, Any]) -> float:
        if not self.g:
            return math.nan
        if len(self.cells) == 1:  # the same digits as before conditions existed
            lost = self.cells[0].lost_per_s()
        else:
            lost = sum(c.lost_per_s() for c in self.cells) / len(self.cells)
        return float(costs["lost_part_cost"]) * lost * SECONDS_PER_HOUR * costs["hours"]

    def lost_cost_half_width(self, costs: Mapping[str, Any], confidence: float) -> float:
        """Half the width of the running cost's interval (lost parts are estimated): the
        cells' half-widths averaged (their runs share seeds, so no independence is assumed)."""
        if not self.g or not float(costs["lost_part_cost"]):
            return 0.0
        half = sum(c.lost_half_width(confidence) for c in self.cells) / len(self.cells)
        return running_per_part(costs) * half

    def gripped_per_s(self) -> float:
        return sum(c.gripped_per_s() for c in self.cells) / len(self.cells) if self.g else 0.0


def paired_lost_difference(a: Config, b: Config, confidence: float) -> tuple[float, float]:
    """The t-interval of b's lost parts per second minus a's, paired over the replications
    both have (common random numbers), averaged over the conditions."""
    n = min(len(a.g), len(b.g))
    diffs = []
    for k in range(n):
        d = 0.0
        for ca, cb in zip(a.cells, b.cells, strict=True):
            d += cb.flow[k] * (1 - cb.g[k] / 100) - ca.flow[k] * (1 - ca.g[k] / 100)
        diffs.append(d / len(a.cells))
    _, low, high = t_interval(diffs, confidence)
    return low, high


def payback(
    new: Config, today: Config, costs: Mapping[str, Any], confidence: float, level: float
) -> dict[str, Any]:
    """What the new line saves a year in lost parts against today's (paired over the
    replications both have: common random numbers), and the months its capital takes to pay
    back, each with its interval at ``confidence`` (the saving's interval bounds the
    payback's). Today's G is shown at ``confidence`` (no selection among baselines)."""
    year = float(costs.get("hours_per_year", costs["hours"]))
    per_part = float(costs["lost_part_cost"]) * SECONDS_PER_HOUR * year
    n = min(len(new.g), len(today.g))
    saved = []
    for k in range(n):
        d = 0.0
        for a, b in zip(today.cells, new.cells, strict=True):
            d += a.flow[k] * (1 - a.g[k] / 100) - b.flow[k] * (1 - b.g[k] / 100)
        saved.append(per_part * d / len(new.cells))
    mean, low, high = t_interval(saved, confidence)
    g = [c.bounds(confidence) for c in today.cells]

    def months(saving: float) -> float | None:
        return 12.0 * new.capital / saving if saving > 0 else None

    return {
        "gripping_rate": min(b[0] for b in g),
        "ci_low": min(b[1] for b in g),
        "ci_high": min(b[2] for b in g),
        "replications": len(today.g),
        "policy": today.policy,
        "capital": new.capital,
        "hours_per_year": year,
        "saving_per_year": mean,
        "saving_low": low,
        "saving_high": high,
        "payback_months": months(mean),
        "payback_months_low": months(high),
        "payback_months_high": months(low),
    }
