"""Work estimates: what a run or a study will cost, known before it starts.

A run holds its whole part stream and its records in memory, so its cost grows with the
parts it feeds: about ``feeder.rate x duration`` (a trace: its rows before ``duration``).
Measured on the paper baseline (``pnp-twin run paper_baseline --set duration=60000``:
600,000 parts, 6.7 s wall time, 540 MB peak resident memory on one core), a part costs
about :data:`BYTES_PER_PART` bytes and :data:`SECONDS_PER_PART` seconds; the 600 s baseline
run with SD processes 19,484 SimPy events for 5,986 parts, :data:`EVENTS_PER_PART`.

Above :data:`MAX_PARTS` parts in one run, or :data:`MAX_RUNS` runs in one study, the
command line refuses with one line saying how to go ahead (``--force``); the limits are
checked from the grid's list lengths, before a study's grid is expanded.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from pnp_twin.twin.errors import UserError
from pnp_twin.twin.scenario import Scenario

MAX_PARTS = 2_000_000  # parts in one run: about 1.6 GB and half a minute
MAX_RUNS = 100_000  # runs in one study
BYTES_PER_PART = 700.0
BASE_BYTES = 180e6  # the interpreter, numpy, pandas, simpy
SECONDS_PER_PART = 1.2e-5
EVENTS_PER_PART = 3.3
FORCE = "or pass --force to run it anyway"


class BudgetError(UserError):
    """The work asked for is above a stated limit; the message says how to go ahead."""


@dataclass(frozen=True)
class RunEstimate:
    """The expected cost of one run."""

    parts: float
    memory_bytes: float
    seconds: float

    @property
    def events(self) -> float:
        """Simulation events, about :data:`EVENTS_PER_PART` per part."""
        return EVENTS_PER_PART * self.parts

    def describe(self) -> str:
        """``about 6e+06 parts (2e+07 events), 4.2 GB, 1.2 min`` (for messages and logs)."""
        return (
            f"about {self.parts:.2g} parts ({self.events:.2g} events), "
            f"{_bytes(self.memory_bytes)}, {_time(self.seconds)}"
        )


def _bytes(n: float) -> str:
    return f"{n / 1e9:.1f} GB" if n >= 1e9 else f"{n / 1e6:.0f} MB"


def _time(s: float) -> str:
    if s >= 3600:
        return f"{s / 3600:.1f} h"
    return f"{s / 60:.1f} min" if s >= 60 else f"{s:.0f} s"


def expected_parts(scenario: Scenario, trace_rows: int | None = None) -> float:
    """Parts a run of ``scenario`` feeds: rate x duration, or the trace's rows."""
    if scenario.feeder.arrival == "trace":
        if trace_rows is None:
            from pnp_twin.twin.trace import check_replay  # the trace's rows (read once more)

            trace = check_replay(scenario)
            trace_rows = 0 if trace is None else len(trace.times)
        return float(trace_rows)
    return scenario.feeder.rate * scenario.duration


def estimate_run(scenario: Scenario, trace_rows: int | None = None) -> RunEstimate:
    """The expected parts, peak memory and wall time of one run of ``scenario``."""
    parts = expected_parts(scenario, trace_rows)
    return RunEstimate(parts, BASE_BYTES + BYTES_PER_PART * parts, SECONDS_PER_PART * parts)


def check_run(scenario: Scenario, force: bool = False, trace_rows: int | None = None) -> None:
    """Refuse (:class:`BudgetError`) a run above :data:`MAX_PARTS` parts, unless ``force``."""
    est = estimate_run(scenario, trace_rows)
    if force or est.parts <= MAX_PARTS:
        return
    f = scenario.feeder
    how = f"{scenario.duration:g} s at {f.rate:g} parts/s" if f.arrival != "trace" else "the trace"
    raise BudgetError(
        f"duration: one run feeds {how}: {est.describe()}; the limit is {MAX_PARTS:,} parts "
        f"per run; shorten duration or lower feeder.rate, {FORCE}"
    )


def _largest(values: Sequence[Any], fallback: float) -> float:
    numbers = [v for v in values if isinstance(v, int | float) and not isinstance(v, bool)]
    return float(max(numbers)) if numbers else fallback


def check_study(
    scenario: Scenario,
    grid: Mapping[str, Sequence[Any]],
    policies: int,
    replications: int,
    force: bool = False,
    extra_points: int = 1,
) -> int:
    """The number of runs of a study (grid x policies x replications x ``extra_points``,
    computed from the list lengths, not by expanding the grid); a :class:`BudgetError`
    above :data:`MAX_RUNS` runs, or when the grid's longest, fastest run is above
    :data:`MAX_PARTS` parts, unless ``force``."""
    sizes = [len(v) for v in grid.values()]
    points = math.prod(sizes) * extra_points
    runs = points * max(policies, 1) * max(replications, 1)
    if not force and runs > MAX_RUNS:
        shape = " x ".join(str(n) for n in sizes) or "1"
        raise BudgetError(
            f"sweep.grid: {shape} values make {points:,} points; with {policies} "
            f"polic{'y' if policies == 1 else 'ies'} and "
            f"{replications} replications that is {runs:,} runs, above the limit of "
            f"{MAX_RUNS:,} per study; thin the grid, {FORCE}"
        )
    sweep = scenario.sweep
    duration = _largest(grid.get("duration", ()), scenario.duration)
    if sweep is not None and sweep.duration is not None:
        duration = sweep.duration
    rate = _largest(grid.get("feeder.rate", ()), scenario.feeder.rate)
    if scenario.feeder.arrival != "trace" and rate * duration > MAX_PARTS and not force:
        est = RunEstimate(rate * duration, BASE_BYTES + BYTES_PER_PART * rate * duration, 0.0)
        raise BudgetError(
            f"duration: the study's longest run feeds {duration:g} s at {rate:g} parts/s, "
            f"about {est.parts:.2g} parts ({_bytes(est.memory_bytes)}); the limit is "
            f"{MAX_PARTS:,} parts per run; shorten the duration (duration, sweep.duration or "
            f"--duration) or lower feeder.rate, {FORCE}"
        )
    return runs
