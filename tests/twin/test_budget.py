"""Work estimates (twin.budget): a run or a study above the stated limits is refused at once,
with one line that says how to go ahead; --force lets it through."""

from __future__ import annotations

import pytest

from pnp_twin.twin.budget import (
    MAX_PARTS,
    MAX_RUNS,
    BudgetError,
    check_run,
    check_study,
    estimate_run,
    expected_parts,
)
from pnp_twin.twin.loader import load_scenario, with_overrides


def test_expected_parts_is_rate_times_duration() -> None:
    scenario = load_scenario("paper_baseline")
    assert expected_parts(scenario) == 10.0 * 600.0
    est = estimate_run(scenario)
    assert est.parts == 6000.0 and est.events > est.parts and est.memory_bytes > 0


def test_a_run_above_the_limit_is_refused_unless_forced() -> None:
    scenario = with_overrides(load_scenario("paper_baseline"), {"duration": 1e6})
    with pytest.raises(BudgetError) as info:
        check_run(scenario)
    message = str(info.value)
    assert "1e+06 s at 10 parts/s" in message and f"{MAX_PARTS:,}" in message
    assert "--force" in message and "GB" in message
    check_run(scenario, force=True)
    check_run(load_scenario("paper_baseline"))


def test_a_huge_grid_is_refused_from_its_list_lengths_at_once() -> None:
    scenario = load_scenario("paper_baseline")
    grid: dict[str, list[float]] = {
        "feeder.rate": [float(r) for r in range(1, 1001)],
        "belt.speed": [0.5] * 1000,
    }
    with pytest.raises(BudgetError) as info:  # from the list lengths: 1e6 points unexpanded
        check_study(scenario, grid, policies=2, replications=5)
    message = str(info.value)
    assert "1000 x 1000" in message and "10,000,000 runs" in message and "--force" in message
    assert check_study(scenario, grid, 2, 5, force=True) == 10_000_000
    assert check_study(scenario, {"feeder.rate": [8, 12]}, 2, 5) == 20 <= MAX_RUNS


def test_the_longest_fastest_run_of_a_grid_is_checked() -> None:
    scenario = with_overrides(load_scenario("paper_baseline"), {"duration": 3600})
    with pytest.raises(BudgetError, match="3600 s at 1000 parts/s"):
        check_study(scenario, {"feeder.rate": [10, 1000]}, 1, 2)
    with pytest.raises(BudgetError, match="1e\\+06 s at 10 parts/s"):
        check_study(scenario, {"duration": [600, 1e6]}, 1, 2)


def test_a_trace_run_counts_its_rows() -> None:
    scenario = load_scenario("trace_replay")
    assert expected_parts(scenario, trace_rows=730) == 730
    check_run(scenario)


def test_a_trace_run_is_estimated_from_its_rows() -> None:
    from pnp_twin.twin.budget import expected_parts

    assert expected_parts(load_scenario("trace_replay")) == 730  # the shipped trace's rows
