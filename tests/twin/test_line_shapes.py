"""Lines as plants build them: kinds of part, robots on both sides and over the belt, reach.

Both engines give the same events on every new shape; parts are conserved per kind; robots
pick only their kinds, only within reach; facing robots share by interception time, not by
their numbers; a mirrored line is symmetric; bad settings are one clear line.
"""

from __future__ import annotations

import math
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pytest

from pnp_twin.policies import make_policy
from pnp_twin.policies.rules import cycle_times
from pnp_twin.twin import simulate
from pnp_twin.twin.decision import Decision
from pnp_twin.twin.loader import load_scenario, shipped_scenarios, with_overrides
from pnp_twin.twin.plan import LinePlan, robot_specs
from pnp_twin.twin.scenario import Scenario
from pnp_twin.twin.stats import t_interval

sys.path.insert(0, str(Path(__file__).parent))
from test_engine_identity import _Cycling, assert_same  # noqa: E402

NEW = ("two_sided", "delta_over_belt", "waste_sorting")
SHORT = {"duration": 30.0, "warmup": 5.0}


def short(name: str, **overrides: Any) -> Scenario:
    return load_scenario(name, {**SHORT, **overrides})


@pytest.mark.parametrize("scheme", ["t_continue", "t_all", "t_any"])
@pytest.mark.parametrize("name", NEW)
@pytest.mark.parametrize("rule", ["FIFO", "SIRO", "SD", "LD", "SPT", "VAL"])
def test_new_shapes_are_event_identical_on_both_engines(name: str, rule: str, scheme: str) -> None:
    bins = {"bins.capacity": 4, "bins.change_time": 0.5}  # a box change per chute
    result = assert_same(short(name, termination=scheme, **bins), rule)
    assert result.kpis["parts_picked"] > 0


@pytest.mark.parametrize("name", NEW)
def test_a_python_policy_sees_the_same_decisions_on_both_engines(name: str) -> None:
    sc = short(name)
    a = simulate(sc, _Cycling(["VAL", "SD", "SPT"]), seed=4, engine="simpy")
    b = simulate(sc, _Cycling(["VAL", "SD", "SPT"]), seed=4, engine="fast")
    for table in ("parts", "spans", "decisions"):
        pd.testing.assert_frame_equal(getattr(a, table), getattr(b, table), check_exact=True)


@pytest.mark.parametrize("name", shipped_scenarios())
def test_parts_are_conserved_per_kind(name: str) -> None:
    sc = load_scenario(name)
    sc = with_overrides(sc, {"duration": min(60.0, sc.duration), "warmup": 5.0})
    k = simulate(sc, make_policy(sc.policy, sc.robots.count), engine="fast").kpis
    assert k["parts_presented"] == k["parts_picked"] + k["parts_missed"]
    if "kinds" not in k:
        assert not sc.feeder.kinds
        return
    kinds = k["kinds"]
    for f in kinds.values():
        assert (
            f["parts_presented"]
            == f["parts_picked"] + f["parts_lost"] + (f["parts_passed_by_design"])
        )
    assert sum(f["parts_picked"] for f in kinds.values()) == k["parts_picked"]
    targeted = sum(f["parts_presented"] for f in kinds.values() if f["targeted"])
    assert targeted == k["parts_presented"]  # untargeted kinds are left out of G
    assert sum(f["parts_passed_by_design"] for f in kinds.values()) == k["parts_passed_by_design"]


def test_robots_pick_only_their_kinds_and_only_within_reach() -> None:
    sc = load_scenario("waste_sorting", {"duration": 120.0, "warmup": 5.0})
    result = simulate(sc, make_policy("VAL", sc.robots.count), engine="fast")
    parts, specs = result.parts, robot_specs(sc)
    picked = parts[parts["outcome"] == "picked"]
    assert len(picked) > 500
    allowed = {i + 1: set(sc.robot_param(i + 1, "kinds")) for i in range(len(specs))}
    for robot, kind in zip(picked["robot"], picked["kind"], strict=True):
        assert kind in allowed[int(robot)], (robot, kind)
    assert (parts.loc[parts["kind"] == "residual", "outcome"] == "missed").all()
    # every grip lies in its robot's x-range and within its reach of the base
    v = sc.belt.speed
    for robot, fed, picked_at, y in picked[["robot", "fed_at", "picked_at", "y"]].itertuples(
        index=False
    ):
        spec = specs[int(robot) - 1]
        x = v * (picked_at - fed)
        a, b = spec.workspace
        assert a - 1e-9 <= x <= b + 1e-9
        assert math.hypot(x - spec.mount[0], y - spec.mount[1]) <= spec.reach + 1e-9


def test_a_reach_shuts_robots_out_of_the_far_side_of_the_belt() -> None:
    """On two_sided each robot reaches 0.7 m from a base 0.1 m off its edge of a 0.8 m belt:
    the far 0.2 m strip is out of its reach, so its picks stay on its own side."""
    sc = load_scenario("two_sided", {"duration": 120.0, "warmup": 5.0})
    parts = simulate(sc, make_policy("SPT", 4), engine="fast").parts
    picked = parts[parts["outcome"] == "picked"]
    upper = picked[picked["robot"].isin([1, 3])]
    lower = picked[picked["robot"].isin([2, 4])]
    assert len(upper) > 300 and len(lower) > 300
    assert upper["y"].min() > 0.8 - 0.6 - 1e-9  # base at y = 0.9, reach 0.7
    assert lower["y"].max() < 0.6 + 1e-9  # base at y = -0.1
    assert upper["y"].mean() > 0.4 > lower["y"].mean()


def _facing(lower_first: bool, **extra: Any) -> Scenario:
    """Two robots sharing one x-range across a belt, the lower one 0.5 m/s faster (so no
    interception ever ties); ``lower_first`` numbers the lower robot 1."""
    fast, slow = {"arm_speed": 3.5, "side": "lower"}, {"arm_speed": 3.0, "side": "upper"}
    first, second = (fast, slow) if lower_first else (slow, fast)
    data: dict[str, Any] = {
        "belt.width": 0.6,
        "robots.count": 2,
        "robots.workspace_length": 0.6,
        "feeder.rate": 9.0,
        "feeder.lateral": "uniform",
        "robots.reach": 0.75,
        "robots.bin_offset": [0.0, 0.2],
        "robots.overrides": [{"robot": 1, **first}, {"robot": 2, **second}],
        "duration": 90.0,
        "warmup": 5.0,
        **extra,
    }
    return with_overrides(Scenario(), data)


@pytest.mark.parametrize("scheme", ["t_continue", "t_all"])
@pytest.mark.parametrize("rule", ["FIFO", "SD", "SPT"])
def test_who_takes_a_part_does_not_depend_on_the_robots_numbers(rule: str, scheme: str) -> None:
    """Exactly, event for event, under t_continue and t_all. (t_any interrupts approaches
    and resumes the robots of an epoch in robot order, as that scheme is defined.)"""
    runs = []
    for lower_first in (False, True):
        sc = _facing(lower_first, termination=scheme)
        parts = simulate(sc, make_policy(rule, 2), seed=3, engine="simpy").parts
        sides = [robot_specs(sc)[int(r) - 1].side for r in parts["robot"].dropna()]
        side = pd.Series(sides, index=parts.index[parts["robot"].notna()])
        runs.append(parts.assign(side=side)[["part", "outcome", "side", "picked_at", "y"]])
    pd.testing.assert_frame_equal(runs[0], runs[1], check_exact=True)
    assert (runs[0]["side"] == "lower").sum() > 50 and (runs[0]["side"] == "upper").sum() > 50


def test_a_mirrored_line_gives_both_sides_the_same_throughput() -> None:
    """Upper robots mirrored by lower ones over a symmetric lateral distribution: the paired
    difference of the two sides' throughput has an interval holding 0."""
    sc = load_scenario("two_sided", {"duration": 120.0, "warmup": 10.0})
    diffs = []
    for seed in range(12):
        robots = simulate(sc, make_policy("SD", 4), seed=seed, engine="fast").kpis["robots"]
        upper = sum(r["throughput"] for r in robots if r["robot"] in (1, 3))
        lower = sum(r["throughput"] for r in robots if r["robot"] in (2, 4))
        diffs.append(upper - lower)
    mean, low, high = t_interval(diffs, 0.95)
    assert low <= 0.0 <= high, (mean, low, high)
    assert abs(mean) < 0.05 * 4.5  # a few % of a side's throughput (about 4.5 parts/s)


def test_value_first_takes_the_valuable_kind_and_keeps_the_cycle_time_rule_on_ties() -> None:
    sc = short("waste_sorting")
    spec = robot_specs(sc)[0]
    d = Decision(spec, 0.0, (0.6, 0.5), [0, 1, 2], [0.5, 0.6, 0.55], [0.5, 0.2, 0.9],
                 [0.1, 0.05, 0.2], [0, 1, 1])  # fmt: skip
    quicker_can = min((1, 2), key=cycle_times(d).__getitem__)
    assert make_policy("VAL", 6).choose(d) == quicker_can == 2  # cans (0.5) beat PET (0.3)
    d_pet = Decision(spec, 0.0, (0.6, 0.5), [0, 1], [0.5, 0.6], [0.5, 0.2], [0.1, 0.05], [0, 0])
    assert make_policy("VAL", 6).choose(d_pet) == make_policy("SPT", 6).choose(d_pet)


def test_kind_grip_times_are_used_per_part() -> None:
    """PET's own grip time (0.08 s against the robots' 0.06 s) lengthens PET cycles only."""
    sc = load_scenario("waste_sorting", {"duration": 60.0, "warmup": 5.0})
    slow = with_overrides(sc, {"feeder.kinds": [
        {"name": "PET", "share": 0.35, "value": 0.3, "pick_time": 0.5},
        {"name": "can", "share": 0.2, "value": 0.5},
        {"name": "residual", "share": 0.45, "value": 0.0},
    ]})  # fmt: skip
    grip = {}
    for label, s in (("base", sc), ("slow", slow)):
        parts = simulate(s, make_policy("VAL", 6), engine="fast").parts
        picked = parts[parts["outcome"] == "picked"]
        cycle = picked["placed_at"] - picked["decided_at"]
        grip[label] = {k: float(cycle[picked["kind"] == k].min()) for k in ("PET", "can")}
    assert grip["slow"]["PET"] >= grip["base"]["PET"] + 0.5 - 0.08 - 0.05
    assert grip["slow"]["can"] < 0.5  # cans keep the robots' grip time


def test_one_kind_lines_draw_as_before_and_have_no_kind_keys() -> None:
    sc = short("paper_baseline")
    plan = LinePlan.of(sc)
    assert plan.kind_table() is None and plan.new_shape() is None and not plan.rivals
    k = simulate(sc, make_policy("SD", 4)).kpis
    assert "kinds" not in k and "value_rate" not in k


def test_a_trace_names_kinds_and_an_unknown_one_is_refused(tmp_path: Path) -> None:
    from pnp_twin.twin.errors import ScenarioError

    trace = tmp_path / "t.csv"
    trace.write_text("time,y,kind\n0.1,0.5,PET\n0.3,0.2,can\n0.5,0.7,residual\n" + "".join(
        f"{0.6 + 0.1 * i:.1f},0.4,can\n" for i in range(300)))  # fmt: skip
    scenario = tmp_path / "s.toml"
    text = Path(str(load_scenario("waste_sorting").source_dir), "waste_sorting.toml").read_text()
    text = text.replace('arrival = "poisson"', f'arrival = "trace"\ntrace = "{trace}"')
    scenario.write_text(text.replace("duration = 600.0", "duration = 20.0").replace(
        "warmup = 60.0", "warmup = 1.0"))  # fmt: skip
    sc = load_scenario(scenario)
    parts = simulate(sc, make_policy("VAL", 6)).parts
    assert parts["kind"].tolist()[:3] == ["PET", "can", "residual"]
    trace.write_text(trace.read_text().replace("0.3,0.2,can", "0.3,0.2,glass"))
    with pytest.raises(ScenarioError, match=r"t.csv' line 3: kind 'glass' is not a kind"):
        load_scenario(scenario)


BAD = [
    ({"feeder.kinds": [{"name": "a", "share": 0.5}, {"name": "b", "share": 0.4}]},
     r"feeder.kinds.share: the shares sum to 0.9; they must sum to 1"),
    ({"feeder.kinds": [{"name": "a", "share": 0.5}, {"name": "a", "share": 0.5}]},
     r"feeder.kinds.name: 'a' is given twice"),
    ({"robots.kinds": ["glass"]}, r"robots.kinds: robot 1 picks 'glass', which is not a kind"),
    ({"robots.side": "left"}, r"robots.side"),
    ({"robots.reach": 0.05, "robots.base_offset": 0.1},
     r"robots.reach: 0.05 m for robot 1 does not touch the belt"),
    ({"robots.reach": 0.3}, r"robots.reach: 0.3 m for robot 1 does not reach its bin"),
    ({"robots.overrides": [{"robot": 2, "side": "lower"}], "robots.workspaces": [
        [0.3, 0.8], [0.3, 0.8], [0.7, 1.0], [1.0, 1.2]]},
     r"robot 3 starts at 0.7 m inside robot 1's workspace \(ends 0.8 m\) on the upper side"),
]  # fmt: skip


@pytest.mark.parametrize(("overrides", "message"), BAD)
def test_bad_line_shapes_are_one_clear_line(overrides: dict[str, Any], message: str) -> None:
    from pnp_twin.twin.errors import ScenarioError

    with pytest.raises(ScenarioError, match=message) as err:
        load_scenario("paper_baseline", overrides)
    assert "\n" not in str(err.value)


def test_facing_robots_share_x_ranges_laid_out_per_side() -> None:
    sc = load_scenario("waste_sorting")
    spaces = [s.workspace for s in robot_specs(sc)]
    assert spaces[0] == spaces[1] and spaces[2] == spaces[3] and spaces[4] == spaces[5]
    assert np.allclose([spaces[0][0], spaces[2][0], spaces[4][0]], [0.3, 0.9, 1.5])
    plan = LinePlan.of(sc)
    assert plan.rivals and plan.targeted == (True, True, False)
    assert sorted(r.priority for r in plan.robots) == list(range(6))


def test_the_vector_envs_refuse_new_shapes_in_one_line() -> None:
    from pnp_twin.learning.vector.batch import LineBatch

    with pytest.raises(ValueError, match="feeder.kinds: the vector environments run lines"):
        LineBatch(short("waste_sorting"), 2, 1, {}, 0, siro=False)


@pytest.mark.parametrize("name", ["two_sided", "waste_sorting"])
def test_the_lookahead_plans_on_the_new_shapes_alike_on_both_engines(name: str) -> None:
    """Its copy of the run (the compiled engine) follows the line decision by decision (it
    stops with an error the moment the two differ), and its futures carry kinds."""
    sc = short(name, duration=15.0, warmup=2.0)
    a = simulate(sc, make_policy("lookahead:K=4,H=0.5", sc.robots.count), engine="simpy")
    b = simulate(sc, make_policy("lookahead:K=4,H=0.5", sc.robots.count), engine="fast")
    pd.testing.assert_frame_equal(a.parts, b.parts, check_exact=True)
    assert a.kpis["parts_picked"] > 0


KINDS = [
    {"name": "a", "share": 0.5, "value": 1.0},
    {"name": "b", "share": 0.3, "value": 2.0, "pick_time": 0.2},
    {"name": "c", "share": 0.2, "value": 3.0, "place_time": 0.15},
]
VARIANTS = {  # paper_baseline with kinds every robot picks: one side, or robots 2 and 4 facing
    "one_side": {"feeder.kinds": KINDS},
    "facing": {
        "feeder.kinds": KINDS,
        "robots.overrides": [{"robot": 2, "side": "lower"}, {"robot": 4, "side": "lower"}],
    },
}


@pytest.mark.parametrize("scheme", ["t_continue", "t_all", "t_any"])
@pytest.mark.parametrize("variant", sorted(VARIANTS))
@pytest.mark.parametrize("rule", ["SPT", "VAL", "SD"])
def test_kinds_every_robot_picks_are_identical_and_timed_per_kind(
    variant: str, rule: str, scheme: str
) -> None:
    """No kind or reach to test: the decisions still carry each part's kind (its grip and
    release times, its value), on both engines alike."""
    sc = short("paper_baseline", termination=scheme, **VARIANTS[variant])
    result = assert_same(sc, rule)
    picked = result.parts[result.parts["outcome"] == "picked"]
    specs, v = robot_specs(sc), sc.belt.speed
    grip = {"a": 0.003694, "b": 0.2, "c": 0.003694}  # the robots', or the kind's own
    release = {"a": 0.003694, "b": 0.003694, "c": 0.15}
    assert set(picked["kind"]) == {"a", "b", "c"}
    for robot, kind, fed, y, at, done in picked[
        ["robot", "kind", "fed_at", "y", "picked_at", "placed_at"]
    ].itertuples(index=False):
        spec = specs[int(robot) - 1]
        x = v * (at - fed)  # where it was gripped
        transfer = math.hypot(spec.bin[0] - x, spec.bin[1] - y) / spec.arm_speed
        assert done - at == pytest.approx(grip[kind] + transfer + release[kind], abs=1e-9)
    if rule == "VAL":
        first = result.parts.groupby("kind")["outcome"].apply(lambda o: (o == "picked").mean())
        assert first["c"] >= first["b"] >= first["a"]  # the valuable kinds are taken first


def test_alternate_sides_face_in_pairs_at_any_robot_count() -> None:
    for count in (1, 2, 5):
        sc = load_scenario("two_sided", {"robots.count": count, "belt.length": 0.3 + 0.5 * 3})
        sides = [s.side for s in robot_specs(sc)]
        assert sides == ["upper" if i % 2 == 0 else "lower" for i in range(count)]
    explicit = load_scenario("two_sided", {"robots.side": "upper", "robots.overrides": [
        {"robot": 2, "side": "lower"}, {"robot": 4, "side": "lower"}]})  # fmt: skip
    assert robot_specs(explicit) == robot_specs(load_scenario("two_sided"))
