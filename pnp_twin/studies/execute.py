"""One run of a study -> one flat row: the function every backend calls.

It is a top-level function of plain data (a :class:`~pnp_twin.studies.plan.RunSpec`), so it
pickles for a process pool and travels as a Ray task unchanged.
"""

from __future__ import annotations

import json
from typing import Any

from pnp_twin.policies import make_policy
from pnp_twin.studies.plan import RunSpec
from pnp_twin.twin.kpis import flat_kpis
from pnp_twin.twin.run import RunResult, simulate
from pnp_twin.twin.trace import for_replication

ID_COLUMNS = ("run_id", "point", "policy", "replication", "seed")
DROPPED = ("policy", "seed")  # flat_kpis repeats these; the row already has them


def cell(value: Any) -> Any:
    """A grid value as a table cell: scalars as they are, lists and tables as JSON text."""
    if isinstance(value, bool | int | float | str) or value is None:
        return value
    return json.dumps(value)


def simulate_spec(spec: RunSpec) -> RunResult:
    """Simulate one run of a study (with several traces, replication k replays trace k)."""
    policy = make_policy(spec.policy, spec.scenario.robots.count)
    scenario = for_replication(spec.scenario, spec.replication)  # trace k in replication k
    return simulate(scenario, policy, seed=spec.seed, policy_name=spec.policy, engine=spec.engine)


def execute(spec: RunSpec) -> dict[str, Any]:
    """Simulate one run and return its row: ids, grid values, every flat KPI, wall time."""
    result = simulate_spec(spec)
    row: dict[str, Any] = {"run_id": spec.run_id, "point": spec.point}
    row.update({path: cell(v) for path, v in spec.values.items()})
    row.update(policy=spec.policy, replication=spec.replication, seed=spec.seed)
    for k, v in flat_kpis(result.kpis).items():
        if k not in DROPPED:
            row[k] = v.item() if hasattr(v, "item") else v
    row["engine"] = result.meta.get("engine", "simpy")  # which engine ran (same results)
    row["wall_time"] = result.wall_time
    return row


def execute_many(specs: list[RunSpec]) -> list[dict[str, Any]]:
    """:func:`execute` on a chunk of specs in one task: short runs sent one by one to a
    pool spend more time travelling between processes than simulating."""
    return [execute(spec) for spec in specs]
