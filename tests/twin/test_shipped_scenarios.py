"""The scenarios shipped in ``scenarios/``: they load by name, run, and mean what they say."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import pytest

from pnp_twin.cli.run_cmd import schema_text
from pnp_twin.policies import make_policy
from pnp_twin.twin import load_scenario, simulate, with_overrides
from pnp_twin.twin.loader import find_scenario, read_mapping, shipped_scenarios, validate
from pnp_twin.twin.scenario import Scenario

SCENARIOS = Path(__file__).resolve().parents[2] / "scenarios"
OURS = ("paper_baseline", "two_robot", "trace_replay", "breakdowns")


def short(scenario: Scenario, duration: float = 90.0) -> Scenario:
    return with_overrides(scenario, {"duration": min(duration, scenario.duration), "warmup": 10})


def test_the_shipped_scenarios_are_listed() -> None:
    assert set(OURS) <= set(shipped_scenarios())


@pytest.mark.parametrize("name", shipped_scenarios())
def test_each_shipped_scenario_loads_and_runs(name: str) -> None:
    scenario = load_scenario(name)
    assert scenario.name == name
    assert scenario.description
    assert scenario.duration <= 600
    result = simulate(short(scenario), make_policy(scenario.policy, scenario.robots.count))
    k = result.kpis
    assert k["parts_presented"] > 0
    assert k["parts_presented"] == k["parts_picked"] + k["parts_missed"]
    assert 0 <= k["gripping_rate"] <= 100
    assert sum(r["picks"] for r in k["robots"]) == k["parts_picked"]
    assert all(0 <= r["utilisation"] <= 1 for r in k["robots"])
    assert result.parts["part"].is_unique


@pytest.mark.parametrize("name", [n for n in OURS if n != "paper_baseline"])
def test_each_scenario_file_explains_its_fields(name: str) -> None:
    text = find_scenario(name).read_text()
    comments = [line for line in text.splitlines() if "#" in line]
    assert len(comments) >= 10


def test_trace_is_read_next_to_the_scenario_from_any_folder(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.chdir(tmp_path)  # not the repository: the relative trace path must still work
    scenario = load_scenario("trace_replay")
    assert scenario.feeder.arrival == "trace"
    assert Path(scenario.source_dir or "") == find_scenario("trace_replay").parent.resolve()
    with (SCENARIOS / "traces" / "sample_line.csv").open() as fh:
        rows = list(csv.DictReader(fh))
    fed = np.array([float(r["time"]) for r in rows])
    result = simulate(scenario, make_policy("SD"))
    w0, w1 = scenario.warmup, scenario.duration
    assert result.kpis["parts_presented"] == int(((fed >= w0) & (fed < w1)).sum())
    assert np.allclose(result.parts["fed_at"], fed[fed < w1], atol=1e-9)
    assert set(result.parts["kind"]) == {"A", "B"}


def test_sample_trace_is_small_and_about_six_parts_per_second() -> None:
    path = SCENARIOS / "traces" / "sample_line.csv"
    assert path.stat().st_size < 100_000
    with path.open() as fh:
        rows = list(csv.DictReader(fh))
    assert list(rows[0]) == ["time", "y", "kind"]
    times = np.array([float(r["time"]) for r in rows])
    ys = np.array([float(r["y"]) for r in rows])
    assert 100 <= times[-1] <= 120
    assert 5.0 <= len(times) / 120 <= 7.0
    assert (np.diff(times) >= 0).all() and ((ys >= 0) & (ys <= 0.4)).all()


def test_two_robot_line_has_two_robots_and_a_lower_flow() -> None:
    two, base = load_scenario("two_robot"), load_scenario("paper_baseline")
    assert two.robots.count == 2
    assert two.feeder.rate < base.feeder.rate
    k = simulate(short(two, 200), make_policy(two.policy)).kpis
    assert k["part_flow"] == pytest.approx(two.feeder.rate, rel=0.1)


def test_breakdowns_cut_availability_and_the_gripping_rate() -> None:
    scenario = load_scenario("breakdowns")
    assert scenario.robots.mtbf == 300 and scenario.robots.mttr == 30
    with_failures = simulate(scenario, make_policy(scenario.policy)).kpis
    without = simulate(
        with_overrides(scenario, {"robots.mtbf": 0}), make_policy(scenario.policy)
    ).kpis
    availability = [r["availability"] for r in with_failures["robots"]]
    assert min(availability) < 1.0
    assert 0.6 < float(np.mean(availability)) < 0.99
    assert all(r["availability"] == 1.0 for r in without["robots"])
    # the same parts arrive in both runs (common random numbers): only the failures differ
    assert with_failures["parts_presented"] == without["parts_presented"]
    assert with_failures["gripping_rate"] < without["gripping_rate"]


def test_committed_schema_matches_the_scenario_model() -> None:
    committed = (SCENARIOS / "scenario.schema.json").read_text()
    assert committed == schema_text(), "run: pnp-twin schema --out scenarios/scenario.schema.json"
    schema = json.loads(committed)
    assert set(schema["properties"]) == set(Scenario.model_fields)


def test_every_default_is_the_paper_baselines_value() -> None:
    """A field left out of a user's file means "as in paper_baseline" (issue #9)."""
    baseline = load_scenario("paper_baseline")
    named = {"name": baseline.name, "description": baseline.description}
    defaults = Scenario.model_validate(named)
    assert defaults.model_dump() == baseline.model_dump()


@pytest.mark.parametrize("name", shipped_scenarios())
def test_shipped_scenarios_are_valid_under_the_strict_rules(name: str) -> None:
    """Each file validates again from its own mapping (strict types, bounds, conflicts)."""
    data = read_mapping(find_scenario(name))
    assert validate(data).model_dump() == load_scenario(name).model_dump()
