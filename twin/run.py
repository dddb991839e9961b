"""Running one scenario with one policy: the small Python API behind ``pnp-twin run``."""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

from pnp_twin.twin.decision import Policy
from pnp_twin.twin.kpis import compute_kpis, recorder_records
from pnp_twin.twin.line import Line
from pnp_twin.twin.scenario import Scenario

if TYPE_CHECKING:
    import pandas as pd


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


class LazyRunResult(RunResult):
    """A RunResult whose tables are built (pandas imported) only when first read."""

    def __init__(
        self,
        base: dict[str, Any],
        builders: dict[str, Callable[[], pd.DataFrame]],
    ) -> None:
        self._builders = builders
        self._tables: dict[str, pd.DataFrame] = {}
        for key, value in base.items():
            setattr(self, key, value)

    def _table(self, name: str) -> pd.DataFrame:
        if name not in self._tables:
            self._tables[name] = self._builders[name]()
        return self._tables[name]

    def __getstate__(self) -> dict[str, Any]:
        """Pickled with its tables built (the builders hold the live run)."""
        for name in self._builders:
            self._table(name)
        return {**self.__dict__, "_builders": {}}

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
    records = recorder_records(rec, line.belt.fed)
    kpis = compute_kpis(*records, line.specs, scenario.warmup, line.duration)
    builders = {
        "parts": lambda: rec.parts_frame(belt, last_end),
        "spans": rec.spans_frame,
        "decisions": rec.decisions_frame,
    }
    meta = {"engine": "simpy", "wall_time": wall, "sim_time": line.now, "seed": line.seed}
    return run_result(scenario, policy_label(policy, policy_name), kpis, meta, builders)


def policy_label(policy: Policy, policy_name: str | None = None) -> str:
    """The name a run's results give its policy."""
    return str(policy_name or getattr(policy, "name", type(policy).__name__))


def run_result(
    scenario: Scenario,
    name: str,
    kpis: dict[str, Any],
    run: dict[str, Any],
    builders: dict[str, Callable[[], pd.DataFrame]],
) -> RunResult:
    """One engine's run as a RunResult: the KPIs headed by what ran, the tables built on
    first read from ``builders``; ``run`` holds the engine, seed, wall and simulated time."""
    head = {"scenario": scenario.name, "policy": name, "seed": run["seed"]}
    base = {
        "scenario": scenario,
        "policy": name,
        "seed": run["seed"],
        "kpis": {**head, "termination": scenario.termination, **kpis},
        "wall_time": run["wall_time"],
        "sim_time": run["sim_time"],
        "meta": {"engine": run["engine"]},
    }
    return LazyRunResult(base, builders)
