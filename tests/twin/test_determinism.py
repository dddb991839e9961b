"""Same seed, same records (bit for bit); different seeds, different records."""

from __future__ import annotations

import pandas as pd
import pytest

from pnp_twin.policies import make_policy
from pnp_twin.twin import simulate

# Every random stream in use: Poisson arrivals, lateral positions, SIRO's policy stream and
# exponential breakdowns, under the scheme with the most interplay (t_any).
RANDOM_LINE = {
    "policy": "SIRO",
    "termination": "t_any",
    "robots.mtbf": 5.0,
    "robots.mttr": 1.0,
    "bins.capacity": 4,
    "bins.change_time": 0.5,
    "duration": 20.0,
}


def run(make_scenario, run_seed: int | None, policy: str = "SIRO", **fields):
    """simulate() on RANDOM_LINE with ``fields`` changed; ``run_seed`` None = the scenario's."""
    return simulate(make_scenario(RANDOM_LINE, **fields), make_policy(policy), seed=run_seed)


def assert_same(a, b) -> None:
    pd.testing.assert_frame_equal(a.parts, b.parts, check_exact=True)
    pd.testing.assert_frame_equal(a.spans, b.spans, check_exact=True)
    pd.testing.assert_frame_equal(a.decisions, b.decisions, check_exact=True)
    assert repr(a.kpis) == repr(b.kpis)  # bit-identical floats (and NaNs), not merely close
    assert a.sim_time == b.sim_time


@pytest.mark.parametrize("scheme", ["t_continue", "t_all", "t_any"])
def test_same_seed_same_records(make_scenario, scheme: str) -> None:
    a = run(make_scenario, 7, termination=scheme)
    b = run(make_scenario, 7, termination=scheme)
    assert len(a.parts) > 100 and (a.spans["state"] == "down").any()
    assert_same(a, b)


def test_the_scenario_seed_is_the_default(make_scenario) -> None:
    a = run(make_scenario, None, seed=11)
    b = run(make_scenario, 11)
    assert a.seed == b.seed == 11
    assert_same(a, b)


def test_different_seeds_differ(make_scenario) -> None:
    a = run(make_scenario, 1)
    b = run(make_scenario, 2)
    assert not a.parts["fed_at"].equals(b.parts["fed_at"])
    assert not a.parts["y"].equals(b.parts["y"])
    assert not a.spans.equals(b.spans)


def test_the_part_stream_does_not_depend_on_the_policy(make_scenario) -> None:
    # common random numbers: every policy faces exactly the same parts for one seed
    runs = [run(make_scenario, 5, policy=p) for p in ("SIRO", "FIFO", "SPT", "SD,LD,SD,LD")]
    for other in runs[1:]:
        pd.testing.assert_frame_equal(
            runs[0].parts[["fed_at", "y"]], other.parts[["fed_at", "y"]], check_exact=True
        )
    # ... while the outcomes do depend on it
    assert len({r.kpis["parts_picked"] for r in runs}) > 1


def test_the_part_stream_does_not_depend_on_the_robots(make_scenario) -> None:
    a = run(make_scenario, 5, robots__count=2)
    b = run(make_scenario, 5, robots__count=4, robots__arm_speed=4.0)
    pd.testing.assert_frame_equal(
        a.parts[["fed_at", "y"]], b.parts[["fed_at", "y"]], check_exact=True
    )


def test_a_run_leaves_no_state_behind(make_scenario) -> None:
    # two different runs in between must not change a third: no module-level state
    first = run(make_scenario, 3)
    run(make_scenario, 4, termination="t_all")
    run(make_scenario, 5, policy="LD")
    again = run(make_scenario, 3)
    assert_same(first, again)
