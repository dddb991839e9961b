"""``simulate`` on the fast engine: the same RunResult as :func:`twin.run.simulate`."""

from __future__ import annotations

import time

from twin.decision import Policy
from twin.fast import unsupported_reason
from twin.fast.engine import FastLine, Unsupported
from twin.kpis import compute_kpis
from twin.run import RunResult
from twin.scenario import Scenario

__all__ = ["Unsupported", "simulate_fast", "unsupported_reason"]


def simulate_fast(
    scenario: Scenario,
    policy: Policy,
    seed: int | None = None,
    policy_name: str | None = None,
) -> RunResult:
    """Run ``scenario`` with a rule mix on the compiled engine and measure it."""
    t0 = time.perf_counter()
    line = FastLine(scenario, policy, seed=seed)
    line.run()
    wall = time.perf_counter() - t0
    rec = line.recorder()
    parts = rec.parts_frame(line.belt, line.last_end)
    spans = rec.spans_frame()
    kpis = compute_kpis(parts, spans, line.specs, scenario.warmup, line.duration)
    name = str(policy_name or getattr(policy, "name", type(policy).__name__))
    kpis = {
        "scenario": scenario.name,
        "policy": name,
        "seed": line.seed,
        "termination": scenario.termination,
        **kpis,
    }
    return RunResult(
        scenario,
        name,
        line.seed,
        kpis,
        parts,
        spans,
        rec.decisions_frame(),
        wall,
        line.now,
        meta={"engine": "fast"},
    )
