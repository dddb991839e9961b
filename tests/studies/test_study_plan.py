"""Study plans: grid expansion, validation of sweep paths and values, CRN seeds."""

from __future__ import annotations

import numpy as np
import pytest

from pnp_twin.studies.plan import StudyError, build_plan, expand_grid, run_id
from pnp_twin.studies.seeds import replication_seeds
from pnp_twin.twin import load_scenario, with_overrides


@pytest.fixture(scope="module")
def line():
    return with_overrides(load_scenario("paper_baseline"), {"duration": 40, "warmup": 5})


def test_grid_is_the_product_last_path_fastest(line):
    plan = build_plan(
        line,
        grid={"robots.arm_speed": [2, 4], "feeder.rate": [8.0, 10.0, 12.0]},
        policies=["SD", "FIFO"],
        replications=3,
    )
    assert len(plan.points) == 6
    assert plan.points[0] == {"robots.arm_speed": 2, "feeder.rate": 8.0}
    assert plan.points[1] == {"robots.arm_speed": 2, "feeder.rate": 10.0}
    assert plan.points[5] == {"robots.arm_speed": 4, "feeder.rate": 12.0}
    assert [sc.robots.arm_speed for sc in plan.scenarios] == [2, 2, 2, 4, 4, 4]
    assert [sc.feeder.rate for sc in plan.scenarios] == [8.0, 10.0, 12.0] * 2
    specs = plan.specs()
    assert len(specs) == 6 * 2 * 3
    assert len({s.run_id for s in specs}) == len(specs)
    assert specs[0].run_id == "p000-SD-r00"
    assert all(s.scenario.duration == 40 for s in specs)


def test_no_grid_is_one_point_with_the_scenario_policy(line):
    plan = build_plan(line, grid={}, replications=2)
    assert plan.points == ({},)
    assert plan.policies == ("SD",)
    assert len(plan.specs()) == 2


def test_sweep_section_sets_duration_and_policies():
    sc = load_scenario("paper_27")
    plan = build_plan(sc)
    assert plan.scenario.duration == 600.0
    assert len(plan.points) == 27 and plan.replications == 5
    assert set(plan.policies) >= {"FIFO", "SD", "SPT", "LD"}
    assert expand_grid({"a": [1, 2], "b": [3]}) == [{"a": 1, "b": 3}, {"a": 2, "b": 3}]


@pytest.mark.parametrize(
    ("grid", "needle"),
    [
        ({"robots.arm_sped": [2, 4]}, "'robots.arm_sped' is not a scenario field"),
        ({"conveyor.speed": [1]}, "'conveyor.speed' is not a scenario field"),
        ({"robots": [1]}, "'robots' is a section"),
        ({"policy.name": [1]}, "'policy' is a value"),
        ({"seed": [1, 2]}, "'seed' cannot be swept"),
        ({"robots.count": "4"}, "is not a non-empty list"),
    ],
)
def test_bad_paths_are_one_line_errors(line, grid, needle):
    with pytest.raises(StudyError) as e:
        build_plan(line, grid=grid)
    assert needle in str(e.value)
    assert "\n" not in str(e.value)


@pytest.mark.parametrize(
    ("grid", "needle"),
    [
        ({"robots.count": [4, "four"]}, 'sweep.grid.robots.count = "four"'),
        ({"feeder.rate": [10, -1]}, "sweep.grid.feeder.rate = -1"),
        ({"feeder.arrival": ["poisson", "bursty"]}, 'sweep.grid.feeder.arrival = "bursty"'),
        ({"robots.arm_speed": [0.5]}, "sweep.grid.robots.arm_speed = 0.5"),
    ],
)
def test_bad_values_name_path_and_value_before_any_run(line, grid, needle):
    with pytest.raises(StudyError) as e:
        build_plan(line, grid=grid)
    assert str(e.value).startswith(needle)
    assert "\n" not in str(e.value)


def test_combination_error_names_the_point(line):
    # 10 robots of 0.2192 m do not fit a 2.4 m belt: neither value is wrong on its own
    with pytest.raises(StudyError, match=r"sweep point \(robots.count=10\): .*belt.length"):
        build_plan(line, grid={"robots.count": [2, 10]})


def test_unknown_policy_is_an_error(line):
    with pytest.raises(StudyError, match="'FOO' is not a rule"):
        build_plan(line, grid={}, policies=["SD", "FOO"])
    with pytest.raises(StudyError, match="names 3 rules for 4 robots"):
        build_plan(line, grid={}, policies=["SD,SD,FIFO"])


def test_crn_same_seed_per_replication_everywhere(line):
    plan = build_plan(
        line, grid={"feeder.rate": [8.0, 12.0]}, policies=["SD", "FIFO", "SPT"], replications=4
    )
    by_rep: dict[int, set[int]] = {}
    for s in plan.specs():
        by_rep.setdefault(s.replication, set()).add(s.seed)
    assert all(len(seeds) == 1 for seeds in by_rep.values())
    seeds = [by_rep[k].pop() for k in range(4)]
    assert len(set(seeds)) == 4
    assert seeds == replication_seeds(line.seed, 4)


def test_seeds_are_spawned_children_and_prefix_stable():
    seeds = replication_seeds(7, 5)
    assert replication_seeds(7, 3) == seeds[:3]  # more replications keep the earlier ones
    assert replication_seeds(8, 5) != seeds
    child = np.random.SeedSequence(7).spawn(5)[2]
    assert seeds[2] == int(child.generate_state(1, dtype=np.uint64)[0]) & ((1 << 53) - 1)
    assert all(0 <= s < 2**53 for s in seeds)


def test_run_ids_are_file_safe_and_distinct():
    assert run_id(3, "SPT,SPT,SPT,FIFO", 1) == "p003-SPT-SPT-SPT-FIFO-r01"
    a, b = run_id(0, "hdqn:runs/a", 0), run_id(0, "hdqn:runs-a", 0)
    assert a != b and "/" not in a and ":" not in a


def test_auto_replications_start_small_and_define_the_study_as_auto(line):
    sweep = {"replications": "auto", "half_width": 0.5, "max_replications": 12}
    sc = with_overrides(line, {f"sweep.{k}": v for k, v in sweep.items()})
    plan = build_plan(sc, grid={"feeder.rate": [8.0]}, policies=["SD"])
    assert plan.replications == 3 and plan.precision is not None
    assert (plan.precision.half_width, plan.precision.max_replications) == (0.5, 12)
    d = plan.definition()
    assert d["replications"] == "auto" and d["precision"]["half_width"] == 0.5
    more = plan.with_replications(7)
    assert more.definition() == d  # a later round is the same study
    assert [s.seed for s in more.specs()][:3] == [s.seed for s in plan.specs()]
    capped = build_plan(with_overrides(sc, {"sweep.max_replications": 2}), grid={})
    assert capped.replications == 2  # the first round never passes the maximum


def test_a_grid_point_running_past_its_trace_is_refused():
    trace = load_scenario("trace_replay")
    build_plan(trace, grid={"duration": [60.0, 100.0]}, replications=2)  # inside the trace
    with pytest.raises(StudyError, match=r"sweep.grid.duration = 5000(.0)?: .*past the end of the"):
        build_plan(trace, grid={"duration": [60.0, 5000.0]}, replications=2)
