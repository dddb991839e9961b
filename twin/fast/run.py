"""``simulate`` on the fast engine: the same RunResult as :func:`twin.run.simulate`.

KPIs come straight from the engine's arrays (:meth:`FastLine.kpi_records` into the twin's
one :func:`twin.kpis.compute_kpis`) and the record tables (pandas) are built only when first
read, so a study run that needs only the KPIs never builds them. Tables and KPIs are the
SimPy engine's, value for value.
"""

from __future__ import annotations

import time
from typing import TYPE_CHECKING, Any

from twin.decision import Policy
from twin.fast.engine import FastLine
from twin.kpis import compute_kpis
from twin.records import Recorder
from twin.run import RunResult
from twin.scenario import Scenario

if TYPE_CHECKING:
    import pandas as pd


class FastRunResult(RunResult):
    """A RunResult whose ``parts``, ``spans`` and ``decisions`` tables are built on first use."""

    def __init__(self, line: FastLine, policy: str, kpis: dict[str, Any], wall: float) -> None:
        self._line = line
        self._tables: dict[str, pd.DataFrame] = {}
        self._rec: Recorder | None = None
        self.scenario = line.scenario
        self.policy = policy
        self.seed = line.seed
        self.kpis = kpis
        self.wall_time = wall
        self.sim_time = line.now
        self.meta = {"engine": "fast"}

    def _recorder(self) -> Recorder:
        if self._rec is None:
            self._rec = self._line.recorder()
        return self._rec

    def _table(self, name: str) -> pd.DataFrame:
        if name not in self._tables:
            rec = self._recorder()
            if name == "parts":
                self._tables[name] = rec.parts_frame(self._line.belt, self._line.last_end)
            elif name == "spans":
                self._tables[name] = rec.spans_frame()
            else:
                self._tables[name] = rec.decisions_frame()
        return self._tables[name]

    @property  # type: ignore[override]
    def parts(self) -> pd.DataFrame:
        return self._table("parts")

    @parts.setter
    def parts(self, value: pd.DataFrame) -> None:
        self._tables["parts"] = value

    @property  # type: ignore[override]
    def spans(self) -> pd.DataFrame:
        return self._table("spans")

    @spans.setter
    def spans(self, value: pd.DataFrame) -> None:
        self._tables["spans"] = value

    @property  # type: ignore[override]
    def decisions(self) -> pd.DataFrame:
        return self._table("decisions")

    @decisions.setter
    def decisions(self, value: pd.DataFrame) -> None:
        self._tables["decisions"] = value


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
    name = str(policy_name or getattr(policy, "name", type(policy).__name__))
    result = FastRunResult(line, name, {}, wall)
    kpis = compute_kpis(*line.kpi_records(), line.specs, scenario.warmup, line.duration)
    result.kpis = {
        "scenario": scenario.name,
        "policy": name,
        "seed": line.seed,
        "termination": scenario.termination,
        **kpis,
    }
    return result
