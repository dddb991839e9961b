"""What a run produced (:class:`RunResult`) and how either engine builds one.

Its own module so that :mod:`twin.run` (which dispatches to the fast engine) and
:mod:`twin.fast.run` both import it without importing each other.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

from pnp_twin.twin.decision import Policy
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
