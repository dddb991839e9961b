"""Writing a study folder (see ``docs/study_format.md``): tables, records, metadata.

Every file is written atomically. The tables are rebuilt from the journal's rows, so a
resumed study ends with exactly the tables an uninterrupted one writes.
"""

from __future__ import annotations

import sys
from collections.abc import Sequence
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import pandas as pd

from pnp_twin.studies.execute import ID_COLUMNS, simulate_spec
from pnp_twin.studies.plan import RunSpec, StudyPlan
from pnp_twin.studies.summary import (
    best_policies,
    paired_differences,
    showcase_point,
    summarise,
)
from pnp_twin.twin.output import versions, write_json, write_table
from pnp_twin.twin.scenario import Scenario
from pnp_twin.twin.trace import check_replays, gap_stats

PACKAGES = ("pnp-twin", "simpy", "numpy", "pandas", "plotly")  # what a result depends on


@dataclass
class Tables:
    """The tables of a study folder."""

    results: pd.DataFrame
    summary: pd.DataFrame
    paired: pd.DataFrame
    best: pd.DataFrame


def now_iso() -> str:
    """The current UTC time, ISO 8601."""
    return datetime.now(UTC).isoformat(timespec="seconds")


def results_frame(rows: Sequence[dict[str, Any]], grid: Sequence[str]) -> pd.DataFrame:
    """One row per run, sorted by point, policy, replication; ids first, wall_time last."""
    ordered = sorted(rows, key=lambda r: (r["point"], r["policy"], r["replication"]))
    df = pd.DataFrame(ordered)
    if df.empty:
        return df
    rules = [c for c in df.columns if c.startswith("rule_")]
    df[rules] = df[rules].fillna(0).astype("int64")
    first = ["run_id", "point", *grid, "policy", "replication", "seed"]
    rest = [c for c in df.columns if c not in first and c != "wall_time"]
    return df[first + rest + ["wall_time"]].reset_index(drop=True)


def build_tables(
    rows: Sequence[dict[str, Any]], grid: Sequence[str], confidence: float = 0.95
) -> Tables:
    """Results, summary, paired differences and best policy per point."""
    results = results_frame(rows, grid)
    summary = summarise(results, grid, confidence)
    best = best_policies(summary, grid)
    paired = paired_differences(results, best, grid, confidence)
    return Tables(results, summary, paired, best)


def write_tables(folder: Path, tables: Tables) -> None:
    """results.parquet/.csv, summary.csv, paired.csv, best.csv."""
    write_table(tables.results, folder / "results.parquet")
    write_table(tables.results, folder / "results.csv")
    write_table(tables.summary, folder / "summary.csv")
    write_table(tables.paired, folder / "paired.csv")
    write_table(tables.best, folder / "best.csv")


def write_records(folder: Path, spec: RunSpec) -> None:
    """Re-simulate one representative run (deterministic) and keep its record tables."""
    result = simulate_spec(spec)
    write_table(result.parts, folder / "records" / "parts.parquet")
    write_table(result.spans, folder / "records" / "spans.parquet")
    write_json(
        {
            "run_id": spec.run_id,
            "point": spec.point,
            "values": spec.values,
            "policy": spec.policy,
            "replication": spec.replication,
            "seed": spec.seed,
            "scenario": spec.scenario.model_dump(mode="json"),
        },
        folder / "records" / "run.json",
    )


def representative(plan: StudyPlan, best: pd.DataFrame) -> RunSpec:
    """Replication 0 of the run the report shows up close (:func:`showcase_point`: the base
    line with its best policy; point 0 and the first policy when there is no best table)."""
    point, policy = 0, plan.policies[0]
    if len(best):
        point, policy = showcase_point(best, plan.grid, plan.scenario.model_dump(mode="json"))
    for spec in plan.specs():
        if spec.point == point and spec.replication == 0 and spec.policy == policy:
            return spec
    raise LookupError(f"no run of point {point} with policy {policy}")


def meta(plan: StudyPlan, kind: str, **extra: Any) -> dict[str, Any]:
    """The meta.json mapping (started_at, wall_time, backend ... come in ``extra``)."""
    return {
        "kind": kind,
        "scenario": plan.scenario.model_dump(mode="json"),
        "scenario_name": plan.scenario.name,
        "master_seed": plan.master_seed,
        "replications": plan.replications,
        "seeds": plan.seeds,
        "duration": plan.scenario.duration,
        "warmup": plan.scenario.warmup,
        "grid": {k: list(v) for k, v in plan.grid.items()},
        "policies": list(plan.policies),
        "runs": len(plan.points) * len(plan.policies) * plan.replications,
        "versions": versions(*PACKAGES),
        "id_columns": list(ID_COLUMNS),
        "argv": sys.argv,
        **trace_info(plan.scenario),
        **extra,
    }


def trace_info(scenario: Scenario) -> dict[str, Any]:
    """``{"trace": {file, parts, mean_rate, cv, traces[, files]}}`` for a scenario that
    replays a trace or several (the rate the report states: a trace ignores ``feeder.rate``;
    with several, their gaps pooled), else {}."""
    traces = check_replays(scenario)
    if not traces:
        return {}
    rate, cv = gap_stats(traces)
    info: dict[str, Any] = {
        "file": traces[0].path.name if len(traces) == 1 else f"{len(traces)} traces",
        "parts": sum(len(t.times) for t in traces),
        "mean_rate": rate,
        "cv": cv,
        "traces": len(traces),
    }
    if len(traces) > 1:
        info["files"] = [t.path.name for t in traces]
    return {"trace": info}
