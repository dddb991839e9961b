"""Placing onto a moving outfeed ([outfeed]): conservation of parts and slots, places inside
each robot's reach, holding, the KPIs, both engines event for event, and bad input."""

from __future__ import annotations

import math
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pytest

from pnp_twin.policies import make_policy
from pnp_twin.twin import simulate
from pnp_twin.twin.fast import mathlib
from pnp_twin.twin.geometry import place_intercept
from pnp_twin.twin.loader import ScenarioError, load_scenario
from pnp_twin.twin.plan import LinePlan
from pnp_twin.twin.records import OUTFEED_COLUMNS, PART_COLUMNS
from pnp_twin.twin.run import RunResult
from pnp_twin.twin.scenario import Scenario

sys.path.insert(0, str(Path(__file__).parent))
from test_engine_identity import assert_same  # noqa: E402

SHORT = {"duration": 30.0, "warmup": 5.0}
LINES = ("tray_loading_coflow", "tray_loading_counterflow")
SCHEMES = ("t_continue", "t_all", "t_any")
SCARCE = {"outfeed.pitch": None, "outfeed.rate": 0.5}  # 3 slots/s for about 8 parts/s picked
STARVED = {"outfeed.pitch": None, "outfeed.rate": 0.01, "warmup": 0.0}  # a tray every 100 s:
# the robots grip a part each and hold it; the second tray comes after the end of the run


def scenario(name: str, **overrides: Any) -> Scenario:
    return load_scenario(name, {**SHORT, **overrides})


def run(sc: Scenario, engine: str = "simpy", policy: str | None = None) -> RunResult:
    return simulate(sc, make_policy(policy or sc.policy, sc.robots.count), engine=engine)


# -- the place leg's geometry -------------------------------------------------------------
@pytest.mark.parametrize("u", [0.3, -0.3, 0.0, 1.2, -1.2])
@pytest.mark.parametrize("acc", [0.0, 15.0])
def test_the_place_leg_meets_the_moving_slot(u: float, acc: float) -> None:
    for dx, dy in [(0.2, 0.5), (-0.3, 0.4), (0.0, 0.6), (0.5, -0.1)]:
        t = place_intercept(dx, dy, u, 3.0, acc)
        assert t >= 0.0
        if acc == 0.0:  # the tool covers the distance to where the slot is at T, at arm speed
            assert math.hypot(dx + u * t, dy) == pytest.approx(3.0 * t, rel=1e-12)
        assert t == mathlib.place_intercept(dx, dy, u, 3.0, acc)  # the compiled twin, exactly


def test_a_slot_moving_towards_the_tool_is_met_sooner() -> None:
    towards, away = place_intercept(0.4, 0.3, -0.5, 3.0), place_intercept(0.4, 0.3, 0.5, 3.0)
    assert towards < place_intercept(0.4, 0.3, 0.0, 3.0) < away


# -- conservation and reach ----------------------------------------------------------------
def _placed(parts: pd.DataFrame) -> pd.DataFrame:
    return parts[parts["container"].notna()]


@pytest.mark.parametrize("name", LINES)
@pytest.mark.parametrize("extra", [{}, SCARCE, STARVED], ids=["shipped", "scarce", "starved"])
def test_every_gripped_part_goes_into_one_slot_or_is_held_at_the_end(
    name: str, extra: dict[str, Any]
) -> None:
    result = run(scenario(name, **extra))
    parts = result.parts
    assert list(parts.columns) == [*PART_COLUMNS, *OUTFEED_COLUMNS]
    picked = parts["outcome"] == "picked"
    placed = parts["container"].notna()
    assert not (placed & ~picked).any()  # only gripped parts are placed
    slots = _placed(parts)[["container", "slot"]].astype(int)
    assert not slots.duplicated().any()  # no slot filled twice
    n_slots = len(scenario(name).outfeed.slots)  # type: ignore[union-attr]
    assert slots["slot"].between(0, n_slots - 1).all()
    held_at_end = picked & ~placed
    assert (parts.loc[held_at_end, "placed_at"].isna()).all()
    assert parts.loc[held_at_end, "held_at"].notna().all()  # a part held at the end waited
    k = result.kpis
    w0, w1 = k["window"]
    window = (parts["fed_at"] >= w0) & (parts["fed_at"] < w1)
    assert k["parts_held_at_end"] == int((held_at_end & window).sum())
    assert k["parts_held"] == int((parts["held_at"].notna() & window).sum())
    if extra is STARVED:
        assert k["parts_held_at_end"] > 0
    else:
        assert k["parts_held_at_end"] == 0 and placed.sum() == picked.sum()


@pytest.mark.parametrize("name", LINES)
@pytest.mark.parametrize("extra", [{}, SCARCE, {"robots.reach": 0.9, "robots.base_offset": 0.1}])
def test_every_place_lies_in_its_robots_range_and_reach(name: str, extra: dict[str, Any]) -> None:
    sc = scenario(name, **extra)
    plan = LinePlan.of(sc)
    out = plan.outfeed
    assert out is not None
    placed = _placed(run(sc).parts)
    assert len(placed) > 50
    for row in placed.itertuples():
        spec = plan.specs[int(row.robot) - 1]
        c, k = int(row.container), int(row.slot)
        a, b = spec.workspace
        y = out.slot_y(k)
        # the release: from the tool meeting the slot until the place time has passed
        for t in (row.placed_at - spec.place_of(0), row.placed_at):
            x = out.slot_x(c, k, t)
            assert a - 1e-9 <= x <= b + 1e-9
            if spec.reach > 0:
                mx, my = spec.mount
                assert math.hypot(x - mx, y - my) <= spec.reach + 1e-9
        assert out.entered_at(c) <= row.placed_at  # the container was there


def test_slots_are_met_at_the_robots_end_of_the_line_they_enter() -> None:
    co = LinePlan.of(scenario("tray_loading_coflow")).outfeed
    counter = LinePlan.of(scenario("tray_loading_counterflow")).outfeed
    assert co is not None and counter is not None
    assert (co.x_in, co.u) == (0.3, 0.3)  # upstream end of the robots' span, moving +x
    assert (counter.x_in, counter.u) == (1.5, -0.3)  # downstream end, moving -x
    # the first robot sees co-flow slots first; the last robot sees counter-flow slots first
    assert min(co.entry[0]) < min(co.entry[2]) and min(counter.entry[2]) < min(counter.entry[0])


def test_a_holding_robot_wakes_when_the_next_slot_enters_its_reach() -> None:
    sc = scenario("tray_loading_coflow", **SCARCE)
    out = LinePlan.of(sc).outfeed
    assert out is not None
    spans = run(sc).spans
    holds = spans[spans["state"] == "holding"]
    assert len(holds) > 10
    for row in holds.itertuples():  # a hold ends at a slot's entry into the robot's interval
        r = int(row.robot) - 1
        ends = [
            c * out.gap + wait
            for wait in out.entry[r]
            if wait < math.inf
            for c in range(int(row.end / out.gap) + 2)
        ]
        assert min(abs(e - row.end) for e in ends) < 1e-9
        assert out.next_entry(r, row.start) <= row.end + 1e-12


# -- KPIs --------------------------------------------------------------------------------------
def test_the_outfeed_kpis_add_up() -> None:
    result = run(scenario("tray_loading_counterflow", **SCARCE))
    k = result.kpis
    span = k["window"][1] - k["window"][0]
    assert 0 < k["containers_full"] <= k["containers"]
    assert k["containers_unfilled"] == k["containers"] - k["containers_full"] == 0  # scarce
    assert k["fill_rate"] == pytest.approx(100.0 * k["containers_full"] / k["containers"])
    assert k["hold_time"] > 0 and k["parts_held"] > 0
    spans = result.spans
    holding = spans[spans["state"] == "holding"]
    clipped = (holding["end"].clip(upper=k["window"][1]) - holding["start"].clip(lower=5.0)).clip(0)
    assert k["hold_time"] == pytest.approx(clipped.sum())
    for r in k["robots"]:
        assert r["blocked"] >= r["hold"] - 1e-12  # holding is blocked time
    assert sum(r["hold"] for r in k["robots"]) * span == pytest.approx(k["hold_time"])
    placed = _placed(result.parts)
    full = placed.groupby("container").size()
    entered = [c for c in full.index if 5.0 <= c * (1 / 0.5) < 30.0]
    assert k["containers_full"] == int((full[entered] == 6).sum())


def test_the_fill_rate_falls_when_the_outfeed_runs_too_fast_for_the_robots() -> None:
    for name in LINES:
        kpis = {u: run(scenario(name, **{"outfeed.speed": u})).kpis for u in (0.3, 0.6)}
        fill = {u: k["fill_rate"] for u, k in kpis.items()}
        assert fill[0.6] < fill[0.3] - 30.0, fill  # twice the slots the robots can fill
        assert kpis[0.6]["containers_unfilled"] > kpis[0.3]["containers_unfilled"]


def test_lines_without_an_outfeed_have_none_of_its_keys_or_columns() -> None:
    result = run(scenario("paper_baseline"))
    assert "fill_rate" not in result.kpis and "hold" not in result.kpis["robots"][0]
    assert list(result.parts.columns) == PART_COLUMNS
    assert LinePlan.of(scenario("paper_baseline")).outfeed is None


# -- both engines ------------------------------------------------------------------------------
@pytest.mark.parametrize("scheme", SCHEMES)
@pytest.mark.parametrize("name", LINES)
@pytest.mark.parametrize("rule", ["FIFO", "SD", "SPT", "SIRO"])
def test_both_engines_give_the_same_events(name: str, rule: str, scheme: str) -> None:
    result = assert_same(scenario(name, termination=scheme), rule)
    assert result.kpis["containers"] > 0 and result.kpis["parts_picked"] > 0


@pytest.mark.parametrize("scheme", SCHEMES)
@pytest.mark.parametrize(
    "extra",
    [
        SCARCE,
        STARVED,  # held until the end of the run
        {"robots.reach": 0.9, "robots.base_offset": 0.1, "robots.acceleration": 20.0},
        {"robots.side": "alternate", "robots.count": 4, "belt.width": 0.6, "outfeed.y": 0.2},
        {"robots.mtbf": 6.0, "robots.mttr": 1.5},
    ],
    ids=["scarce", "held_at_end", "reach_acc", "facing", "breakdowns"],
)
def test_both_engines_agree_on_harder_outfeed_lines(extra: dict[str, Any], scheme: str) -> None:
    result = assert_same(scenario("tray_loading_counterflow", termination=scheme, **extra), "SPT")
    assert result.kpis["parts_picked"] > 0
    if extra is STARVED:
        assert result.kpis["parts_held_at_end"] > 0


# -- tools that refuse the shape, and bad input --------------------------------------------
def test_the_vector_env_and_the_lookahead_refuse_an_outfeed_line() -> None:
    from pnp_twin.learning.envs.vector_env import PickPlaceVectorEnv
    from pnp_twin.policies.lookahead import LookaheadError

    sc = scenario("tray_loading_coflow")
    assert LinePlan.of(sc).new_shape() == "outfeed"
    with pytest.raises(ValueError, match=r"^outfeed: the vector environments run") as e:
        PickPlaceVectorEnv(num_envs=2, scenario=sc)
    assert "\n" not in str(e.value)
    with pytest.raises(LookaheadError, match=r"^outfeed: the lookahead's rollouts"):
        simulate(sc, make_policy("lookahead:K=2,H=1", 3))


BAD = {
    "slot outside": (
        {"outfeed.slots": [[0.0, 0.0], [0.1, 0.0]]},
        "outfeed.slots: slot 2 [0.1, 0] lies outside the 0.18 x 0.12 m container; "
        "allowed |dx| <= 0.09, |dy| <= 0.06",
    ),
    "pitch short": (
        {"outfeed.pitch": 0.15},
        "outfeed.pitch: containers 0.15 m apart are shorter than a container "
        "(outfeed.container_length = 0.18 m); give a pitch of at least 0.18 m",
    ),
    "rate high": (
        {"outfeed.pitch": None, "outfeed.rate": 2.0},
        "outfeed.rate: containers 0.15 m apart are shorter than a container "
        "(outfeed.container_length = 0.18 m); give a rate of at most 1.667 containers/s",
    ),
    "unreachable": (
        {"robots.reach": 0.6, "outfeed.y": 1.3},
        "outfeed.y: no robot reaches an outfeed at y = 1.3 m",
    ),
    "zero speed": ({"outfeed.speed": 0.0}, "outfeed.speed: 0 is not allowed"),
    "negative speed": ({"outfeed.speed": -0.3}, "outfeed.speed: -0.3 is not allowed"),
    "too fast for the arms": ({"outfeed.speed": 6.0}, "outfeed.speed: 6 m/s is not below"),
    "both": ({"outfeed.rate": 1.0}, "outfeed.pitch: both of outfeed.pitch and outfeed.rate"),
    "neither": ({"outfeed.pitch": None}, "outfeed.pitch: neither of outfeed.pitch and"),
    "boxes": ({"bins.capacity": 4}, "bins: capacity and change_time do not apply"),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_outfeeds_are_refused_in_one_line(case: str) -> None:
    overrides, expected = BAD[case]
    with pytest.raises(ScenarioError) as e:
        scenario("tray_loading_coflow", **overrides)
    message = str(e.value)
    assert message.startswith(expected), message
    assert "\n" not in message


def test_both_shipped_lines_differ_only_in_direction() -> None:
    co, counter = scenario("tray_loading_coflow"), scenario("tray_loading_counterflow")
    a = co.model_dump(exclude={"name", "description"})
    b = counter.model_dump(exclude={"name", "description"})
    assert a["outfeed"].pop("direction") == "co" and b["outfeed"].pop("direction") == "counter"
    assert a == b
    assert np.isfinite(run(co).kpis["fill_rate"])


def test_a_study_may_sweep_the_outfeeds_fields() -> None:
    from pnp_twin.studies.plan import field_path_error

    assert field_path_error("outfeed.speed") is None
    assert field_path_error("outfeed.direction") is None
    assert "is a section" in str(field_path_error("outfeed"))
    assert "not a scenario field" in str(field_path_error("outfeed.sped"))


@pytest.mark.parametrize("arrival", ["poisson", "normal"])
@pytest.mark.parametrize("scheme", ["t_continue", "t_all", "t_any"])
def test_containers_arriving_at_random_are_identical_on_both_engines(
    arrival: str, scheme: str
) -> None:
    """Drawn gaps (from the containers' own stream, never shorter than a container): the
    same events on both engines, and the parts the same as with fixed spacing."""
    extra = {"outfeed.arrival": arrival, "outfeed.cv": 0.6, "termination": scheme}
    sc = load_scenario("tray_loading_counterflow", {"duration": 60.0, "warmup": 5.0, **extra})
    result = assert_same(sc, "SPT")
    times = np.asarray(LinePlan.of(sc).outfeed.times)  # type: ignore[union-attr]
    gaps = np.diff(times)
    out = sc.outfeed
    assert out is not None
    assert gaps.min() >= out.min_gap - 1e-12 and gaps.std() > 0.05 * gaps.mean()
    assert times[-1] > LinePlan.of(sc).end_at
    fixed = load_scenario("tray_loading_counterflow", {"duration": 60.0, "warmup": 5.0})
    base = simulate(fixed, make_policy("SPT", 3)).parts
    assert np.array_equal(base["fed_at"], result.parts["fed_at"])  # the part stream is kept
    k = result.kpis
    assert k["containers"] == int(((times >= 5.0) & (times < 60.0)).sum())
