"""Robot breakdowns (availability as configured) and bins (capacity, box changes)."""

from __future__ import annotations

import numpy as np
import pytest

from pnp_twin.policies import make_policy
from pnp_twin.twin import simulate
from pnp_twin.twin.line import Line

# A light feed and a coarse belt grid keep long runs cheap (fewer NooP looks).
LONG = {"feeder.rate": 4.0, "belt.grid": [8, 8], "warmup": 5.0}


def test_no_breakdowns_by_default(make_scenario) -> None:
    r = simulate(make_scenario(), make_policy("SD"))
    assert not (r.spans["state"] == "down").any()
    assert [x["availability"] for x in r.kpis["robots"]] == [1.0] * 4
    assert [x["down"] for x in r.kpis["robots"]] == [0.0] * 4


def test_fixed_breakdowns_follow_mtbf_and_mttr(make_scenario) -> None:
    m, rr = 20.0, 5.0
    line = {
        **LONG,
        "duration": 600.0,
        "robots.mtbf": m,
        "robots.mttr": rr,
        "robots.failure_distribution": "fixed",
        # robot 3 is worse: 10 s up, 10 s down
        "robots.overrides": [{"robot": 3, "mtbf": 10.0, "mttr": 10.0}],
    }
    r = simulate(make_scenario(line), make_policy("SD"))
    down = r.spans[r.spans["state"] == "down"]
    for robot, (mtbf, mttr) in enumerate([(m, rr), (m, rr), (10.0, 10.0), (m, rr)]):
        mine = down[down["robot"] == robot + 1].sort_values("start")  # tables: robot 1 first
        assert len(mine) > 20
        # every repair takes exactly mttr
        assert np.allclose(mine["end"] - mine["start"], mttr, rtol=0, atol=1e-9)
        # the next failure is due mtbf after a repair; it takes effect at the robot's next
        # decision point (it never drops a part), so up time is mtbf plus at most a cycle
        up = mine["start"].to_numpy()[1:] - mine["end"].to_numpy()[:-1]
        assert (up >= mtbf - 1e-9).all() and (up < mtbf + 1.5).all(), up
        assert mine["start"].iloc[0] == pytest.approx(mtbf, abs=1.5)
        availability = r.kpis["robots"][robot]["availability"]
        assert availability == pytest.approx(mtbf / (mtbf + mttr), abs=0.02)


def test_exponential_breakdowns_give_the_expected_availability(make_scenario) -> None:
    m, rr = 8.0, 2.0
    line = {**LONG, "duration": 1500.0, "robots.mtbf": m, "robots.mttr": rr}
    r = simulate(make_scenario(line), make_policy("SD"))
    down = r.spans[r.spans["state"] == "down"]
    lengths = (down["end"] - down["start"]).to_numpy()
    assert len(lengths) > 400  # about 150 failures per robot
    # repair times are exponential with mean mttr: mean ~ sd ~ 2 (se about 0.1)
    assert lengths.mean() == pytest.approx(rr, rel=0.15)
    assert lengths.std() == pytest.approx(rr, rel=0.2)
    avail = [x["availability"] for x in r.kpis["robots"]]
    # M / (M + R) = 0.8; the per-robot estimate has an sd of about 0.015
    assert np.mean(avail) == pytest.approx(m / (m + rr), abs=0.025)
    assert all(a == pytest.approx(m / (m + rr), abs=0.06) for a in avail), avail
    # robots fail independently (one stream each): their down spans do not coincide
    starts = [set(down.loc[down["robot"] == i, "start"].round(6)) for i in range(4)]
    assert not starts[0] & starts[1]


def test_breakdowns_cost_picks(make_scenario) -> None:
    base = simulate(make_scenario(duration=120.0), make_policy("SD")).kpis["gripping_rate"]
    line = {"duration": 120.0, "robots.mtbf": 6.0, "robots.mttr": 4.0}
    broken = simulate(make_scenario(line), make_policy("SD")).kpis["gripping_rate"]
    assert broken < base - 5.0


def run_line(scenario):
    """Run a Line directly, to look at its bins after the run."""
    line = Line(scenario, make_policy("SD"))
    line.run()
    parts = line.recorder.parts_frame(line.belt, line.last_end)
    return line, parts, line.recorder.spans_frame()


@pytest.mark.parametrize(("capacity", "change"), [(5, 2.0), (3, 0.7), (1, 1.0)])
def test_box_changes_block_placing(make_scenario, capacity: int, change: float) -> None:
    sc = make_scenario({"bins.capacity": capacity, "bins.change_time": change})
    line, parts, spans = run_line(sc)
    picked = parts[parts["outcome"] == "picked"]
    blocked = spans[spans["state"] == "blocked"]
    assert len(blocked) > 0
    place = sc.robots.place_time
    for robot in range(4):
        mine = picked[picked["robot"] == robot + 1].sort_values("placed_at")  # robot 1 first
        # one box change per `capacity` parts placed
        assert line.robots[robot].bin.boxes == len(mine) // capacity
        done = mine["placed_at"].to_numpy()
        start = done - place  # when each release began
        wait = mine["blocked_time"].to_numpy()
        for j in range(1, len(mine)):
            if j % capacity == 0:  # the box was full: the new one is ready `change` later
                assert start[j] >= done[j - 1] + change - 1e-9
                if wait[j] > 0:  # blocked until exactly then
                    assert start[j] == pytest.approx(done[j - 1] + change, abs=1e-9)
            else:
                assert wait[j] == 0.0
        assert wait[0] == 0.0
        # a blocked span sits inside the busy cycle of the part it delayed
        spans_r = blocked[blocked["robot"] == robot + 1]
        delayed = mine[mine["blocked_time"] > 0]
        assert len(spans_r) == len(delayed)
        for (s, e), (_, p) in zip(
            spans_r[["start", "end"]].to_numpy(), delayed.iterrows(), strict=True
        ):
            assert p["decided_at"] <= s < e <= p["placed_at"] - place + 1e-9
            assert e - s == pytest.approx(p["blocked_time"], abs=1e-9)
    kpi_blocked = [x["blocked"] for x in simulate(sc, make_policy("SD")).kpis["robots"]]
    assert max(kpi_blocked) > 0.0


def test_unlimited_bins_never_block(make_scenario) -> None:
    line, parts, spans = run_line(make_scenario({"bins.change_time": 5.0}))  # capacity 0
    assert not (spans["state"] == "blocked").any()
    assert (parts["blocked_time"] == 0.0).all()
    assert [r.bin.boxes for r in line.robots] == [0, 0, 0, 0]


def test_box_changes_cost_picks(make_scenario) -> None:
    base = simulate(make_scenario(duration=60.0), make_policy("SD")).kpis["gripping_rate"]
    line = {"duration": 60.0, "bins.capacity": 2, "bins.change_time": 1.5}
    slowed = simulate(make_scenario(line), make_policy("SD")).kpis["gripping_rate"]
    assert slowed < base - 5.0
