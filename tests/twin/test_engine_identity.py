"""The fast engine produces the SimPy twin's events exactly: parts, spans, decisions, KPIs.

A matrix over the shipped scenarios, every rule and a per-robot mix, the three termination
schemes, breakdowns, bins, acceleration limits, trace replay and seeds, plus a hypothesis
property over random valid lines. Runs are short (tens of simulated seconds).
"""

from __future__ import annotations

import json
import math
import subprocess
import sys
from typing import Any

import numpy as np
import pandas as pd
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from pnp_twin.policies import RuleChoosingPolicy, make_policy
from pnp_twin.twin import simulate
from pnp_twin.twin.decision import Decision
from pnp_twin.twin.fast import EngineError
from pnp_twin.twin.loader import load_scenario, with_overrides
from pnp_twin.twin.run import RunResult
from pnp_twin.twin.scenario import Scenario

SHORT = {"duration": 30.0, "warmup": 5.0}
SCHEMES = ("t_continue", "t_all", "t_any")
RULES = ("FIFO", "LIFO", "SIRO", "SD", "LD", "SPT")


def _kpi_text(kpis: dict[str, Any]) -> str:
    return json.dumps(kpis, sort_keys=True, default=str)  # NaN -> NaN, compared as text


def assert_same(scenario: Scenario, policy: str, seed: int | None = None) -> RunResult:
    """Run both engines; every table and KPI must be identical (floats bit for bit)."""
    n = scenario.robots.count
    a = simulate(scenario, make_policy(policy, n), seed=seed, engine="simpy")
    b = simulate(scenario, make_policy(policy, n), seed=seed, engine="fast")
    assert a.meta["engine"] == "simpy" and b.meta["engine"] == "fast"
    pd.testing.assert_frame_equal(a.parts, b.parts, check_exact=True)
    pd.testing.assert_frame_equal(a.spans, b.spans, check_exact=True)
    pd.testing.assert_frame_equal(a.decisions, b.decisions, check_exact=True)
    assert _kpi_text(a.kpis) == _kpi_text(b.kpis)
    assert a.sim_time == b.sim_time
    return b


def scenario(name: str, **overrides: Any) -> Scenario:
    return load_scenario(name, {**SHORT, **overrides})


@pytest.mark.parametrize("scheme", SCHEMES)
@pytest.mark.parametrize(
    "name", ["paper_baseline", "two_robot", "trace_replay", "breakdowns", "paper_27"]
)
@pytest.mark.parametrize("rule", RULES)
def test_shipped_scenarios_every_rule_and_scheme(name: str, rule: str, scheme: str) -> None:
    result = assert_same(scenario(name, termination=scheme), rule)
    assert result.kpis["parts_presented"] > 0


@pytest.mark.parametrize("scheme", SCHEMES)
@pytest.mark.parametrize(
    "mix", ["SPT,SPT,SPT,FIFO", "SIRO,SD,SIRO,LD", "LIFO,SIRO,SPT,FIFO", "SD,SD,SD,SIRO"]
)
def test_per_robot_mixes(mix: str, scheme: str) -> None:
    assert_same(scenario("paper_baseline", termination=scheme), mix)


@pytest.mark.parametrize("seed", [0, 1, 7, 123])
@pytest.mark.parametrize("rule", ["SIRO", "SPT", "SD"])
def test_seeds(seed: int, rule: str) -> None:
    assert_same(scenario("paper_baseline"), rule, seed=seed)


FEATURES = {
    "bins": {"bins.capacity": 6, "bins.change_time": 1.5},
    "bins_every_part": {"bins.capacity": 1, "bins.change_time": 0.4},
    "acceleration": {"robots.acceleration": 9.0},
    "acceleration_and_bins": {
        "robots.acceleration": 12.0,
        "bins.capacity": 4,
        "bins.change_time": 0.8,
    },
    "fixed_breakdowns": {
        "robots.mtbf": 7.0,
        "robots.mttr": 2.0,
        "robots.failure_distribution": "fixed",
    },
    "exp_breakdowns": {"robots.mtbf": 6.0, "robots.mttr": 1.5},
    "normal_gaps_uniform": {"feeder.arrival": "normal", "feeder.lateral": "uniform"},
    "fixed_feed": {"feeder.arrival": "fixed", "feeder.rate": 9.0},
    "gaps_and_overrides": {
        "robots.workspace_gap": 0.05,
        "robots.workspace_length": 0.45,
        "robots.overrides": [
            {"robot": 2, "arm_speed": 4.5, "acceleration": 6.0, "mtbf": 5.0, "mttr": 1.0},
            {"robot": 4, "pick_time": 0.2, "bin_offset": [0.1, 0.3]},
        ],
    },
}


@pytest.mark.parametrize("scheme", SCHEMES)
@pytest.mark.parametrize("feature", sorted(FEATURES))
@pytest.mark.parametrize("policy", ["SPT", "SD,LIFO,SIRO,FIFO"])
def test_features(feature: str, scheme: str, policy: str) -> None:
    assert_same(scenario("paper_baseline", termination=scheme, **FEATURES[feature]), policy)


def test_a_full_baseline_hour_of_feeding() -> None:
    """Long enough for every rare branch the short runs might miss (one run per engine)."""
    assert_same(load_scenario("paper_baseline", {"duration": 900.0}), "SPT", seed=3)


def test_unknown_engines_are_refused() -> None:
    with pytest.raises(EngineError, match="'turbo' is not an engine; allowed simpy, fast, auto"):
        simulate(scenario("two_robot"), make_policy("SD", 2), engine="turbo")


def test_cli_engine_option_records_the_engine() -> None:
    from typer.testing import CliRunner

    from pnp_twin.cli import app

    args = ["run", "two_robot", "--set", "duration=20", "--set", "warmup=2", "--json"]
    out = {}
    for engine in ("simpy", "fast"):
        res = CliRunner().invoke(app, [*args, "--engine", engine])
        assert res.exit_code == 0, res.output
        out[engine] = json.loads(res.stdout)
    assert out["simpy"].pop("engine") == "simpy" and out["fast"].pop("engine") == "fast"
    assert out["simpy"] == out["fast"]
    res = CliRunner().invoke(app, [*args, "--engine", "turbo"])
    assert res.exit_code == 2


def test_importing_twin_does_not_import_numba() -> None:
    code = "import sys, twin, twin.fast; print('numba' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"


@st.composite
def lines(draw: st.DrawFn) -> tuple[Scenario, str, int]:
    n = draw(st.integers(1, 4))
    length = draw(st.floats(0.2, 0.6))
    belt_speed = draw(st.floats(0.3, 1.2))
    data: dict[str, Any] = {
        "robots.count": n,
        "robots.workspace_length": length,
        "robots.workspace_gap": draw(st.sampled_from([0.0, 0.1])),
        "belt.length": 0.3 + n * (length + 0.1) + 0.1,
        "belt.speed": belt_speed,
        "robots.arm_speed": belt_speed + draw(st.floats(0.5, 4.0)),
        "robots.pick_time": draw(st.floats(0.0, 0.3)),
        "robots.place_time": draw(st.floats(0.0, 0.3)),
        "robots.acceleration": draw(st.sampled_from([0.0, 0.0, 5.0, 20.0])),
        "feeder.rate": draw(st.floats(1.0, 20.0)),
        "feeder.arrival": draw(st.sampled_from(["poisson", "normal", "fixed"])),
        "bins.capacity": draw(st.sampled_from([0, 0, 1, 5])),
        "bins.change_time": draw(st.sampled_from([0.0, 0.5, 2.0])),
        "termination": draw(st.sampled_from(SCHEMES)),
        "duration": 20.0,
        "warmup": 2.0,
    }
    if draw(st.booleans()):
        data["robots.mtbf"] = draw(st.floats(2.0, 20.0))
        data["robots.mttr"] = draw(st.floats(0.1, 5.0))
        data["robots.failure_distribution"] = draw(st.sampled_from(["exponential", "fixed"]))
    rules = draw(st.lists(st.sampled_from(RULES), min_size=n, max_size=n))
    policy = rules[0] if draw(st.booleans()) else ",".join(rules)
    sc = with_overrides(Scenario(), data)
    return sc, policy, draw(st.integers(0, 2**31 - 1))


@settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(lines())
def test_random_lines_are_identical(case: tuple[Scenario, str, int]) -> None:
    sc, policy, seed = case
    result = assert_same(sc, policy, seed=seed)
    kpis = result.kpis
    assert kpis["parts_picked"] + kpis["parts_missed"] == kpis["parts_presented"]
    assert math.isnan(kpis["gripping_rate"]) or 0.0 <= kpis["gripping_rate"] <= 100.0


class _Cycling(RuleChoosingPolicy):
    """A Python policy: the mix's rules in turn, decision by decision (SIRO draws too)."""

    name = "cycling"

    def __init__(self, rules: list[str]) -> None:
        super().__init__()
        self.cycle, self.j = rules, 0

    def select_rule(self, decision: Decision) -> str:
        self.j += 1
        return self.cycle[(self.j + decision.robot) % len(self.cycle)]


@settings(max_examples=20, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(lines())
def test_random_lines_with_a_python_policy_are_identical(case: tuple[Scenario, str, int]) -> None:
    """The callback path (the kernel stops, Python answers) over random valid lines."""
    sc, policy, seed = case
    rules = policy.split(",")
    a = simulate(sc, _Cycling(rules), seed=seed, engine="simpy")
    b = simulate(sc, _Cycling(rules), seed=seed, engine="fast")
    for table in ("parts", "spans", "decisions"):
        pd.testing.assert_frame_equal(getattr(a, table), getattr(b, table), check_exact=True)
    assert _kpi_text(a.kpis) == _kpi_text(b.kpis)


def test_kpis_from_the_engine_arrays_equal_kpis_from_its_tables() -> None:
    """One KPI code: the fast engine's arrays and its record tables give the same KPIs."""
    from pnp_twin.twin.fast.engine import FastLine
    from pnp_twin.twin.kpis import compute_kpis, table_kpis

    for name, rule in [("breakdowns", "SIRO"), ("paper_baseline", "SPT"), ("trace_replay", "LD")]:
        sc = scenario(name, termination="t_any", **{"bins.capacity": 5, "bins.change_time": 1.0})
        line = FastLine(sc, make_policy(rule, sc.robots.count))
        line.run()
        rec = line.recorder()
        parts, spans = rec.parts_frame(line.belt, line.last_end), rec.spans_frame()
        ref = table_kpis(parts, spans, line.specs, sc.warmup, line.duration)
        got = compute_kpis(*line.kpi_records(), line.specs, sc.warmup, line.duration)
        assert list(got) == list(ref) and _kpi_text(got) == _kpi_text(ref)
        assert ref["parts_picked"] > 0 and ref["decisions"][rule] == ref["parts_picked"]


@pytest.mark.parametrize("scheme", SCHEMES)
def test_a_run_forked_midway_continues_identically(scheme: str) -> None:
    """State is arrays: stop anywhere, copy, continue; both copies end as one straight run."""
    from pnp_twin.twin.fast.engine import STATE, FastLine

    sc = scenario("breakdowns", termination=scheme, **{"bins.capacity": 4})
    whole = FastLine(sc, make_policy("SIRO", sc.robots.count))
    whole.run()
    part = FastLine(sc, make_policy("SIRO", sc.robots.count))
    part.start(*part._rooms())
    assert part.advance(12.5) == 0 and 0.0 < part.now < 12.5
    fork = part.fork()
    assert fork.holder is not part.holder
    for line in (part, fork):
        assert line.advance(line.end_at) == 0 and line.finish() == 0
        for name in STATE:
            if not name.startswith("_"):
                np.testing.assert_array_equal(getattr(line, name), getattr(whole, name))
