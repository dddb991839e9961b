"""The figure a study's target is on (``--kpi`` of ``size``, ``design``, ``capacity`` and
``headroom``): the gripping rate (the default), the value rate, or one kind's gripping rate.

* ``gripping_rate``: G, parts gripped / parts presented, % (kinds no robot picks left out);
* ``value_rate``: % of the value presented that was gripped (a line with ``feeder.kinds``);
  on a line without kinds every part has the same value, so it is G;
* ``gripping_rate:KIND``: G of one kind of ``feeder.kinds`` that some robot picks (a kind no
  robot picks passes on by design and has no gripping rate).

:func:`parse_kpi` checks a choice against a scenario (a one-line :class:`StudyError`, exit
code 2 on the command line, otherwise); :meth:`KpiChoice.of` reads the figure from a run's
KPI dictionary (``result.kpis``) and :attr:`KpiChoice.column` names it in a study's flat rows
(:func:`pnp_twin.twin.kpis.flat_kpis`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from pnp_twin.studies.plan import StudyError
from pnp_twin.twin.errors import excerpt
from pnp_twin.twin.scenario import Scenario

GRIPPING_RATE = "gripping_rate"
VALUE_RATE = "value_rate"
NAMES = (GRIPPING_RATE, VALUE_RATE)


@dataclass(frozen=True)
class KpiChoice:
    """One checked ``--kpi`` choice (:func:`parse_kpi`)."""

    name: str = GRIPPING_RATE
    """As given: gripping_rate, value_rate or gripping_rate:KIND."""
    kind: str | None = None
    """KIND of gripping_rate:KIND."""
    column: str = GRIPPING_RATE
    """The figure's column in a study's flat rows (value_rate on a line without kinds: G's)."""

    @property
    def default(self) -> bool:
        """The gripping rate: every study's output as before ``--kpi`` existed."""
        return self.name == GRIPPING_RATE

    @property
    def noun(self) -> str:
        """'gripping rate', 'value rate', 'PET gripping rate'."""
        if self.kind is not None:
            return f"{self.kind} gripping rate"
        return self.name.replace("_", " ")

    @property
    def short(self) -> str:
        """How an answer writes the figure: 'G', 'value rate', 'PET gripping rate'."""
        return "G" if self.default else self.noun

    def of(self, kpis: Mapping[str, Any]) -> float:
        """The figure in a run's KPI dictionary (NaN where no part of it was presented)."""
        if self.kind is not None:
            return float(kpis["kinds"][self.kind]["gripping_rate"])
        if self.name == VALUE_RATE and VALUE_RATE in kpis:
            return float(kpis[VALUE_RATE])
        return float(kpis[GRIPPING_RATE])

    def flow(self, kpis: Mapping[str, Any]) -> tuple[float, str]:
        """What the figure's percentage is of, per second of the window, and its unit: the
        parts presented (G), the value presented (value rate) or the kind's parts."""
        flow = float(kpis["part_flow"])
        presented = kpis.get("parts_presented") or 0
        kinds = kpis.get("kinds") or {}
        if self.kind is not None:
            share = kinds[self.kind]["parts_presented"] / presented if presented else math.nan
            return flow * share, f"{self.kind} parts"
        if self.name == VALUE_RATE and kinds:
            worth = math.fsum(k["value_presented"] for k in kinds.values())
            return (flow * worth / presented if presented else math.nan), "in value"
        return flow, "parts"

    def to_json(self) -> dict[str, Any]:
        """A study file's ``kpi``: the name, what it is called and its column."""
        return {"name": self.name, "label": self.noun, "column": self.column}


GRIPPING = KpiChoice()


def kind_targeted(scenario: Scenario) -> dict[str, bool]:
    """Each kind of ``feeder.kinds``: whether some robot of the line picks it."""
    from pnp_twin.twin.plan import LinePlan

    plan = LinePlan.of(scenario)
    return dict(zip(plan.kinds, plan.targeted, strict=True))


def parse_kpi(text: str | None, scenario: Scenario) -> KpiChoice:
    """``--kpi`` checked against ``scenario``; a one-line StudyError otherwise."""
    if text is None:
        return GRIPPING
    given = text.strip()
    kinds = [k.name for k in scenario.feeder.kinds]
    name, sep, kind = given.partition(":")
    if name not in NAMES or (sep and name != GRIPPING_RATE):
        picked = [k for k, on in kind_targeted(scenario).items() if on] if kinds else []
        allowed = [*NAMES, *(f"{GRIPPING_RATE}:{k}" for k in picked)]
        raise StudyError(f"--kpi: {excerpt(text)} is not allowed; allowed {', '.join(allowed)}")
    if not sep:
        if name == VALUE_RATE and kinds:
            return KpiChoice(VALUE_RATE, None, VALUE_RATE)
        return KpiChoice(name, None, GRIPPING_RATE)
    if not kinds:
        raise StudyError(
            f"--kpi {excerpt(given)}: {scenario.name} has one kind of part (no feeder.kinds); "
            f"give {GRIPPING_RATE} or {VALUE_RATE}"
        )
    if kind not in kinds:
        raise StudyError(
            f"--kpi {excerpt(given)}: {excerpt(kind)} is not a kind of {scenario.name}; its "
            f"kinds (feeder.kinds) are {', '.join(kinds)}"
        )
    if not kind_targeted(scenario)[kind]:
        raise StudyError(
            f"--kpi {excerpt(given)}: no robot picks {kind}; it passes on by design; it has no "
            "gripping rate"
        )
    return KpiChoice(f"{GRIPPING_RATE}:{kind}", kind, f"kind_{kind}_{GRIPPING_RATE}")
