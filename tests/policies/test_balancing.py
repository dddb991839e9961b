"""The line controllers' balancing modes: share, lane and list, each with a rule.

Parts get an owner when they are fed; a robot picks only what it owns (or, with
``unreached=release``, what its owner upstream left), in its rule's order; both engines give
the same events; bad modes are one line.
"""

from __future__ import annotations

import re
from typing import Any

import numpy as np
import pandas as pd
import pytest
from typer.testing import CliRunner

from pnp_twin.cli import app
from pnp_twin.policies import make_policy
from pnp_twin.policies.balancing import BalancingError, BalancingPolicy
from pnp_twin.twin import simulate
from pnp_twin.twin.loader import load_scenario
from pnp_twin.twin.plan import robot_specs
from pnp_twin.twin.stats import t_interval

LOW = {"feeder.rate": 2.0, "duration": 200.0, "warmup": 20.0}  # every robot keeps up


def picks_by_owner(policy: BalancingPolicy, parts: pd.DataFrame) -> pd.DataFrame:
    """The picked parts with their owner (0-based) as the policy gave them."""
    picked = parts[parts["outcome"] == "picked"]
    owners = [
        policy.owner_of(int(p), float(y)) for p, y in zip(picked["part"], picked["y"], strict=True)
    ]
    return picked.assign(owner=owners, by=picked["robot"].astype(int) - 1)


@pytest.mark.parametrize(
    "spec", ["share:40,30,30,100", "list:1,2,3,4,2", "lane:0-0.1,0.1-0.2,0.2-0.3,0.3-0.4"]
)
@pytest.mark.parametrize("scheme", ["t_continue", "t_all", "t_any"])
def test_balancing_modes_are_identical_on_both_engines(spec: str, scheme: str) -> None:
    sc = load_scenario("paper_baseline", {"duration": 30.0, "warmup": 5.0, "termination": scheme})
    a = simulate(sc, make_policy(f"{spec};rule=SPT", 4), engine="simpy")
    b = simulate(sc, make_policy(f"{spec};rule=SPT", 4), engine="fast")
    for table in ("parts", "spans", "decisions"):
        pd.testing.assert_frame_equal(getattr(a, table), getattr(b, table), check_exact=True)
    assert a.kpis["decisions"]["NooP"] > 0  # robots passed over parts they do not own


def test_a_robot_picks_only_what_it_owns() -> None:
    for spec in ("share:40,30,30,100", "list:1,2,3,4,2", "lane:0-0.15,0.15-0.2,0.2-0.25,0.25-0.4"):
        sc = load_scenario("paper_baseline", {"duration": 120.0, "warmup": 10.0})
        policy = make_policy(spec, 4)
        assert isinstance(policy, BalancingPolicy)
        parts = simulate(sc, policy).parts
        picked = picks_by_owner(policy, parts)
        assert len(picked) > 300
        assert (picked["by"] == picked["owner"]).all(), spec


def test_list_follows_its_sequence_and_lane_its_bands() -> None:
    sc = load_scenario("paper_baseline", LOW)
    parts = simulate(sc, make_policy("list:1,2,3,4,2", 4)).parts
    picked = parts[parts["outcome"] == "picked"]
    seq = np.array([1, 2, 3, 4, 2])
    assert (picked["robot"].astype(int).to_numpy() == seq[picked["part"].to_numpy() % 5]).all()
    assert len(picked) / len(parts) > 0.95  # at low load each owner gets its parts
    lanes = [(0.0, 0.15), (0.15, 0.2), (0.2, 0.25), (0.25, 0.4)]
    parts = simulate(sc, make_policy("lane:0-0.15,0.15-0.2,0.2-0.25,0.25-0.4", 4)).parts
    picked = parts[parts["outcome"] == "picked"]
    for robot, y in zip(picked["robot"].astype(int), picked["y"], strict=True):
        lo, hi = lanes[robot - 1]
        assert lo <= y <= hi


def test_share_gives_each_robot_its_share_of_the_parts_reaching_it() -> None:
    """At low load on a line whose robots reach every part (two_robot at 1 part/s), robot
    i's picks over the parts that reached it (not taken upstream) is its share, within the
    replications' interval."""
    shares = [35.0, 100.0]
    got: list[list[float]] = [[] for _ in shares]
    for seed in range(6):
        sc = load_scenario("two_robot", {"feeder.rate": 1.0, "duration": 300.0, "seed": seed})
        kpis = simulate(sc, make_policy("share:35,100", 2), engine="fast").kpis
        assert kpis["gripping_rate"] > 99.0  # every owner picks what it owns
        reaching = kpis["parts_presented"]
        for i, r in enumerate(kpis["robots"]):
            got[i].append(100.0 * r["picks"] / reaching)
            reaching -= r["picks"]
    for i, share in enumerate(shares):
        mean, low, high = t_interval(got[i], 0.95)
        assert low - 0.5 <= share <= high + 0.5, (i, mean, low, high)


def test_share_owners_are_counted_as_a_controller_counts() -> None:
    """paper_baseline's share:40,30,30,100: owners are exactly 40 % of all parts, 30 % of
    the 60 % left, 30 % of the 42 % left and the rest, part by part (no random draw)."""
    policy = make_policy("share:40,30,30,100", 4)
    assert isinstance(policy, BalancingPolicy)
    policy.reset(robot_specs(load_scenario("paper_baseline")), np.random.default_rng(0))
    owners = np.array([policy.owner_of(p, 0.2) for p in range(10_000)])
    shares = np.bincount(owners, minlength=4) / len(owners)
    assert np.allclose(shares, [0.40, 0.18, 0.126, 0.294], atol=2e-3)
    assert policy.owner[:5] == [0, 1, 0, 2, 3]  # 1 of 1, 1 of 1, 2 of 3, 1 of 1, all


def test_unreached_parts_are_released_downstream_when_allowed() -> None:
    """A fast flow with robot 1 owning most parts: it misses some; with release the robots
    downstream take those (and only parts whose owner is upstream of them)."""
    sc = load_scenario("paper_baseline", {"feeder.rate": 14.0, "duration": 120.0, "warmup": 10.0})
    lost = make_policy("share:90,10,10,100", 4)
    kept = simulate(sc, lost).kpis["gripping_rate"]
    released = make_policy("share:90,10,10,100;unreached=release", 4)
    result = simulate(sc, released)
    assert result.kpis["gripping_rate"] > kept + 5.0
    picked = picks_by_owner(released, result.parts)
    others = picked[picked["by"] != picked["owner"]]
    assert len(others) > 50 and (others["by"] > others["owner"]).all()


BAD: list[tuple[str, str]] = [
    ("share:40,30,130,100", "share 130 is outside 0..100"),
    ("share:40,30,30", "3 shares for 4 robots; give one per robot"),
    ("share:40,x,30,100", "'x' is not a number"),
    ("lane:0-0.2,0.1-0.3,0.3-0.35,0.35-0.4", "lane 0.1-0.3 m overlaps the lane below it"),
    ("lane:0-0.1,0.2-0.3,0.3-0.35,0.35-0.4", "the lanes leave a gap from y = 0.1 to 0.2 m"),
    ("lane:0-0.1,0.1-0.2,0.2-0.3,0.3-0.35", "the lanes end at y = 0.35 m"),
    ("list:1,2,5", "robot 5 is not a robot; allowed 1..4"),
    ("share:40,30,30,100;rule=XYZ", "'rule=XYZ' is not a setting"),
]


@pytest.mark.parametrize(("spec", "message"), BAD)
def test_bad_modes_are_one_line_and_exit_2(spec: str, message: str) -> None:
    with pytest.raises(BalancingError, match=re.escape(message)):
        sc = load_scenario("paper_baseline", {"duration": 5.0, "warmup": 1.0})
        simulate(sc, make_policy(spec, 4))
    sets = ["--set", "duration=5", "--set", "warmup=1"]
    res = CliRunner().invoke(app, ["run", "paper_baseline", "--policy", spec, *sets])
    assert res.exit_code == 2
    lines = res.output.strip().splitlines()
    assert len(lines) == 1 and message in lines[0]


def test_the_controller_line_says_what_to_type() -> None:
    policy: Any = make_policy("share:38,33,29,100;rule=SPT", 4)
    assert policy.settings.controller_line() == (
        "robot 1: 38 %, robot 2: 33 %, robot 3: 29 %, robot 4: 100 %"
    )
    assert policy.name == "share:38,33,29,100;rule=SPT"
    assert [s.index for s in robot_specs(load_scenario("paper_baseline"))] == [0, 1, 2, 3]
