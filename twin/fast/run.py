"""``simulate`` on the fast engine: the same RunResult as :func:`twin.run.simulate`.

KPIs come straight from the engine's arrays (:meth:`FastLine.kpis`: the sums of
:func:`twin.kpis.compute_kpis` in one compiled pass, the dictionary built by the same code)
and the record tables (pandas) are built only when first read, so a study run that needs
only the KPIs never builds them. Tables and KPIs are the
SimPy engine's, value for value.
"""

from __future__ import annotations

import functools
import time

from pnp_twin.twin.decision import Policy
from pnp_twin.twin.fast.engine import FastLine
from pnp_twin.twin.result import RunResult, policy_label, run_result
from pnp_twin.twin.scenario import Scenario


def simulate_fast(
    scenario: Scenario,
    policy: Policy,
    seed: int | None = None,
    policy_name: str | None = None,
) -> RunResult:
    """Run ``scenario`` with ``policy`` on the compiled engine and measure it."""
    t0 = time.perf_counter()
    line = FastLine(scenario, policy, seed=seed)
    line.run()
    wall = time.perf_counter() - t0
    recorder = functools.cache(line.recorder)  # the tables' source, built on first read
    builders = {
        "parts": lambda: recorder().parts_frame(line.belt, line.last_end),
        "spans": lambda: recorder().spans_frame(),
        "decisions": lambda: recorder().decisions_frame(),
    }
    kpis = line.kpis(scenario.warmup)  # the sums in one compiled pass
    meta = {"engine": "fast", "wall_time": wall, "sim_time": line.now, "seed": line.seed}
    return run_result(scenario, policy_label(policy, policy_name), kpis, meta, builders)
