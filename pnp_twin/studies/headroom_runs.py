"""How a ``headroom`` run is kept in the runs store (:mod:`pnp_twin.studies.runstore`).

A headroom study journals every run the moment it finishes in ``DIR/evals/runs.sqlite``, so a
killed study resumes: its finished runs are read back, the others simulated, and the final
tables are those of an uninterrupted study. A run's key hashes what decides its result: the
resolved scenario, the policy spec (with the size and modification time of every file a
spec such as ``hdqn:DIR`` or ``py:FILE`` names, so a retrained model is run again), the seed
and the figure compared (``--kpi``). Its stored KPIs: ``figure`` (the ``--kpi`` figure),
``part_flow``, ``figure_flow`` and ``figure_unit`` (the figure's own flow, :meth:`KpiChoice.flow`)
and, for a policy that reports it, ``cpu_ms_per_decision`` (as measured when it ran).
"""

from __future__ import annotations

import hashlib
import json
import math
from pathlib import Path
from typing import Any

from pnp_twin.studies.kpi_choice import KpiChoice
from pnp_twin.twin.scenario import Scenario

One = tuple[float, float | None, float, tuple[float, str]]
"""A run's figure, CPU ms per decision (None: not reported), part flow, (figure flow, unit)."""
STAMP_FILES = 200  # files of a policy folder whose size and time enter the key, at most


def scene(scenario: Scenario) -> dict[str, Any]:
    """The scenario as the key sees it (its name and description change no result)."""
    return scenario.model_dump(mode="json", exclude={"source_dir", "name", "description"})


def run_key(scene: dict[str, Any], spec: str, seed: int, kpi: KpiChoice) -> str:
    """The store's key of one headroom run."""
    what = {
        "study": "headroom",
        "scenario": scene,
        "policy": spec,
        "files": policy_stamp(spec),
        "seed": seed,
        "kpi": kpi.name,
    }
    text = json.dumps(what, sort_keys=True, default=str)
    return hashlib.sha1(text.encode()).hexdigest()[:24]


def policy_stamp(spec: str) -> list[tuple[str, int, int]]:
    """(name, size, mtime in ns) of the files a ``prefix:PATH`` spec names; [] for a rule."""
    _, sep, arg = spec.strip().partition(":")
    if not sep:
        return []
    for text in dict.fromkeys((arg, arg.split(",")[0], arg.rsplit(":", 1)[0])):
        path = Path(text) if text else None
        if path is None or not path.exists():
            continue
        files = [path] if path.is_file() else sorted(p for p in path.rglob("*") if p.is_file())
        out = []
        for p in files[:STAMP_FILES]:
            st = p.stat()
            out.append((str(p), st.st_size, st.st_mtime_ns))
        return out
    return []


def to_row(one: One) -> dict[str, Any]:
    """The stored KPIs of one run."""
    figure, cpu, flow, (figure_flow, unit) = one
    row: dict[str, Any] = {
        "figure": figure,
        "part_flow": flow,
        "figure_flow": figure_flow,
        "figure_unit": unit,
    }
    if cpu is not None:
        row["cpu_ms_per_decision"] = cpu
    return row


def from_row(row: dict[str, Any] | None) -> One | None:
    """One run read back; None when absent or not a headroom run's row (run it again)."""
    if row is None:
        return None
    numbers = ("figure", "part_flow", "figure_flow")
    if not all(_number(row.get(k)) for k in numbers) or not isinstance(row.get("figure_unit"), str):
        return None
    cpu = row.get("cpu_ms_per_decision")
    if cpu is not None and not _number(cpu):
        return None
    return (
        float(row["figure"]),
        None if cpu is None else float(cpu),
        float(row["part_flow"]),
        (float(row["figure_flow"]), str(row["figure_unit"])),
    )


def _number(value: Any) -> bool:
    return (
        isinstance(value, int | float)
        and not isinstance(value, bool)
        and not (isinstance(value, float) and math.isinf(value))
    )
