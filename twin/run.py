"""Running one scenario with one policy: the small Python API behind ``pnp-twin run``."""

from __future__ import annotations

import time

import numpy as np

from pnp_twin.twin.decision import Policy
from pnp_twin.twin.kpis import compute_kpis, recorder_records
from pnp_twin.twin.line import Line
from pnp_twin.twin.result import LazyRunResult, RunResult, policy_label, run_result
from pnp_twin.twin.scenario import Scenario

__all__ = ["LazyRunResult", "RunResult", "policy_label", "run_result", "simulate"]


def simulate(
    scenario: Scenario,
    policy: Policy,
    seed: int | None = None,
    policy_name: str | None = None,
    engine: str = "simpy",
) -> RunResult:
    """Run ``scenario`` with ``policy`` (seed defaults to the scenario's) and measure it.

    ``engine``: "simpy" (this module), "fast" (the compiled :mod:`twin.fast`, same events,
    any policy) or "auto" (fast); ``meta["engine"]`` says which ran.
    """
    if engine != "simpy":
        from pnp_twin.twin.fast import pick_engine, simulate_fast

        if pick_engine(engine, policy) == "fast":
            return simulate_fast(scenario, policy, seed=seed, policy_name=policy_name)
    t0 = time.perf_counter()
    line = Line(scenario, policy, seed=seed)
    line.run()
    wall = time.perf_counter() - t0
    rec = line.recorder
    rec.close_open_spans(line.now)  # idempotent; for Line subclasses with their own run()
    belt, last_end = line.belt, line.last_end
    parts, spans = recorder_records(rec, line.belt.fed)
    kinds = line.plan.kind_table()
    if kinds is not None:
        parts = kinds.with_records(parts, np.asarray(belt.kind_code, dtype=np.int64))
    kpis = compute_kpis(
        parts, spans, line.specs, scenario.warmup, line.duration, kinds, line.plan.outfeed
    )
    builders = {
        "parts": lambda: rec.parts_frame(belt, last_end),
        "spans": rec.spans_frame,
        "decisions": rec.decisions_frame,
    }
    meta = {"engine": "simpy", "wall_time": wall, "sim_time": line.now, "seed": line.seed}
    return run_result(scenario, policy_label(policy, policy_name), kpis, meta, builders)
