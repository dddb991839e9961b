"""What each stored configuration of a sweep or sizing study costs, with ``--costs FILE``
(the TOML of ``pnp-twin design``: ``robot_price``, ``belt_price``, ``lost_part_cost``,
``hours``): capital (robots x robot price at the arm speed + belt price at the belt speed)
plus lost_part_cost x part flow x (1 - G) x 3600 x hours, with the mean part flow and G of
each point x policy. Kept in ``meta.json`` as ``costs`` (an analysis setting: another cost
file reuses every stored run), shown by the report's what-if panel."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from pnp_twin.studies.folder import Tables
from pnp_twin.studies.plan import StudyPlan
from pnp_twin.studies.prices import SECONDS_PER_HOUR, capital, read_costs
from pnp_twin.twin.scenario import Scenario

__all__ = ["check_costs", "read_costs", "study_costs"]


def check_costs(costs: Mapping[str, Any], scenarios: Sequence[Scenario]) -> None:
    """Refuse (one line, before anything runs) a cost file that prices no arm or belt speed
    the study runs."""
    for sc in scenarios:
        capital(costs, sc)


def study_costs(
    plan: StudyPlan, tables: Tables, costs: Mapping[str, Any], file: str | Path
) -> dict[str, Any]:
    """meta.json's ``costs``: the file, its prices and each point x policy's total cost."""
    results = tables.results
    flows = results.groupby(["point", "policy"])["part_flow"].mean() if len(results) else {}
    rows = []
    for _, r in tables.summary.iterrows():
        point, policy = int(r["point"]), str(r["policy"])
        buy = capital(costs, plan.scenarios[point])
        g = float(r["gripping_rate_mean"])
        flow = float(flows.get((point, policy), math.nan)) if len(results) else math.nan
        lost = float(costs["lost_part_cost"]) * flow * (1.0 - g / 100.0)
        lost *= SECONDS_PER_HOUR * float(costs["hours"])
        rows.append(
            {
                "point": point,
                "policy": policy,
                "capital": buy,
                "lost_parts_cost": lost,
                "total_cost": buy + lost if math.isfinite(lost) else buy,
            }
        )
    prices = {
        k: ({f"{s:g}": p for s, p in v.items()} if isinstance(v, dict) else v)
        for k, v in costs.items()
    }
    return {"file": Path(file).name, "prices": prices, "rows": rows}
