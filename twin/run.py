"""Running one scenario with one policy: the small Python API behind ``pnp-twin run``."""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any

import pandas as pd

from twin.decision import Policy
from twin.kpis import compute_kpis, recorder_records
from twin.line import Line
from twin.scenario import Scenario


@dataclass
class RunResult:
    """What one run produced: KPIs and the record tables."""

    scenario: Scenario
    policy: str
    seed: int
    kpis: dict[str, Any]
    parts: pd.DataFrame
    spans: pd.DataFrame
    decisions: pd.DataFrame
    wall_time: float
    sim_time: float
    meta: dict[str, Any] = field(default_factory=dict)


def simulate(
    scenario: Scenario,
    policy: Policy,
    seed: int | None = None,
    policy_name: str | None = None,
    engine: str = "simpy",
) -> RunResult:
    """Run ``scenario`` with ``policy`` (seed defaults to the scenario's) and measure it.

    ``engine``: "simpy" (this module), "fast" (the compiled :mod:`twin.fast`, same events,
    rule policies only) or "auto" (fast where it can, else simpy); ``meta["engine"]`` says
    which ran.
    """
    if engine != "simpy":
        from twin.fast import pick_engine, simulate_fast

        if pick_engine(engine, policy) == "fast":
            return simulate_fast(scenario, policy, seed=seed, policy_name=policy_name)
    t0 = time.perf_counter()
    line = Line(scenario, policy, seed=seed)
    line.run()
    wall = time.perf_counter() - t0
    rec = line.recorder
    rec.close_open_spans(line.now)  # idempotent; for Line subclasses with their own run()
    parts = rec.parts_frame(line.belt, line.last_end)
    spans = rec.spans_frame()
    records = recorder_records(rec, line.belt.fed)
    kpis = compute_kpis(*records, line.specs, scenario.warmup, line.duration)
    name = str(policy_name or getattr(policy, "name", type(policy).__name__))
    kpis = {
        "scenario": scenario.name,
        "policy": name,
        "seed": line.seed,
        "termination": scenario.termination,
        **kpis,
    }
    return RunResult(
        scenario, name, line.seed, kpis, parts, spans, rec.decisions_frame(), wall, line.now,
        meta={"engine": "simpy"},
    )
