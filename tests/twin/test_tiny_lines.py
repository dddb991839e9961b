"""Hand-built tiny lines (one robot, one or two parts) against timings worked out by hand.

The expected values are computed here, independently of the twin, from MODEL.md: the
interception time T solves (x_p + v_b T - P_x)^2 + (y_p - P_y)^2 = (v_r T)^2 from the tool
position P (the robot's base at the start: workspace centre x, belt centre y; its bin after
a place), picked_at = decided_at + T, and
placed_at = picked_at + pick_time + |bin - intercept point| / v_r + place_time.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from pnp_twin.policies import make_policy
from pnp_twin.twin import simulate
from pnp_twin.twin.geometry import intercept_time, move_time

V_B, V_R, PICK, PLACE = 0.5, 2.0, 0.1, 0.15
WIDTH = 0.4


def tiny_line(trace: Path, workspace: tuple[float, float], **extra: object) -> dict:
    """One robot on a 1 m belt at 0.5 m/s, arm 2 m/s, bin 0.1 m downstream of its workspace
    centre and 0.2 m beyond the upper edge; parts replayed from ``trace``."""
    return {
        "belt": {"length": 1.0, "width": WIDTH, "speed": V_B, "grid": [64, 8]},
        "feeder": {"arrival": "trace", "trace": str(trace)},
        "robots": {
            "count": 1,
            "workspaces": [list(workspace)],
            "arm_speed": V_R,
            "pick_time": PICK,
            "place_time": PLACE,
            "bin_offset": [0.1, 0.2],
            **extra,
        },
        "duration": 5.0,
        "warmup": 0.0,
    }


def base_of(workspace: tuple[float, float]) -> tuple[float, float]:
    return ((workspace[0] + workspace[1]) / 2.0, WIDTH / 2.0)


def bin_of(workspace: tuple[float, float]) -> tuple[float, float]:
    return ((workspace[0] + workspace[1]) / 2.0 + 0.1, WIDTH + 0.2)


def intercept(x: float, y: float, tool: tuple[float, float]) -> float:
    """The smallest non-negative root of the interception quadratic (numpy.roots)."""
    dx, dy = x - tool[0], y - tool[1]
    roots = np.roots([V_R**2 - V_B**2, -2.0 * V_B * dx, -(dx * dx + dy * dy)])
    return min(r.real for r in roots if abs(r.imag) < 1e-12 and r.real >= 0.0)


def test_one_part_from_the_base(make_scenario, write_trace, tmp_path) -> None:
    ws = (0.0, 0.6)
    trace = write_trace(tmp_path / "one.csv", [(0.0, 0.1)])
    r = simulate(make_scenario(tiny_line(trace, ws)), make_policy("SD"))
    assert len(r.parts) == 1
    p = r.parts.iloc[0]
    assert p["outcome"] == "picked" and p["robot"] == 1 and p["rule"] == "SD"
    assert p["decided_at"] == 0.0  # the part is on the belt when the run starts
    t = intercept(0.0, 0.1, base_of(ws))  # the tool starts at the robot's base
    assert t == pytest.approx(0.128127, abs=1e-6)  # worked by hand once, as a sanity anchor
    assert p["picked_at"] == pytest.approx(t, abs=1e-12)
    hit = (V_B * t, 0.1)
    placed = t + PICK + math.dist(hit, bin_of(ws)) / V_R + PLACE
    assert p["placed_at"] == pytest.approx(placed, abs=1e-12)
    assert p["left_at"] == pytest.approx(t, abs=1e-12)  # the part leaves the belt at the grip
    assert r.kpis["gripping_rate"] == 100.0
    assert r.kpis["decisions"]["SD"] == 1


def test_second_part_starts_from_the_bin(make_scenario, write_trace, tmp_path) -> None:
    ws = (0.0, 0.6)
    trace = write_trace(tmp_path / "two.csv", [(0.0, 0.1), (0.5, 0.3)])
    r = simulate(make_scenario(tiny_line(trace, ws)), make_policy("FIFO"))
    first, second = r.parts.iloc[0], r.parts.iloc[1]
    assert (r.parts["outcome"] == "picked").all()
    # the robot is free at the first place and the second part is then a candidate
    assert second["decided_at"] == first["placed_at"]
    now = second["decided_at"]
    x2 = V_B * (now - 0.5)
    t2 = intercept(x2, 0.3, bin_of(ws))  # the tool waits at the bin after placing
    assert second["picked_at"] == pytest.approx(now + t2, abs=1e-12)
    hit = (x2 + V_B * t2, 0.3)
    assert ws[0] <= hit[0] <= ws[1]
    placed = now + t2 + PICK + math.dist(hit, bin_of(ws)) / V_R + PLACE
    assert second["placed_at"] == pytest.approx(placed, abs=1e-12)


def test_robot_noops_until_the_part_becomes_a_candidate(
    make_scenario, write_trace, tmp_path
) -> None:
    ws = (0.3, 0.8)
    trace = write_trace(tmp_path / "late.csv", [(1.0, 0.3)])
    r = simulate(make_scenario(tiny_line(trace, ws)), make_policy("SD"))
    p = r.parts.iloc[0]
    assert p["outcome"] == "picked"
    tick = (1.0 / 64) / V_B  # the belt moves one grid cell
    noops = r.spans[(r.spans["state"] == "noop") & (r.spans["end"] <= p["decided_at"])]
    # before the part, the robot looked once per belt tick (NooPs back to back from t = 0)
    assert noops["start"].iloc[0] == 0.0
    assert np.allclose(noops["end"] - noops["start"], tick, rtol=0, atol=1e-12)
    assert noops["end"].iloc[-1] == p["decided_at"]

    def hit_x(now: float) -> float:  # where the tool, from the base, would meet the part
        x = V_B * (now - 1.0)
        return x + V_B * intercept(x, 0.3, base_of(ws))

    k = round(p["decided_at"] / tick)
    assert p["decided_at"] == pytest.approx(k * tick, abs=1e-9)
    # the first look at which the interception point lies inside the workspace
    assert hit_x(p["decided_at"]) >= ws[0]
    assert hit_x(p["decided_at"] - tick) < ws[0]
    t = intercept(V_B * (p["decided_at"] - 1.0), 0.3, base_of(ws))
    assert p["picked_at"] == pytest.approx(p["decided_at"] + t, abs=1e-12)


def test_a_part_passing_a_busy_robot_is_missed(make_scenario, write_trace, tmp_path) -> None:
    ws = (0.0, 0.6)
    trace = write_trace(tmp_path / "pair.csv", [(0.0, 0.1), (0.0, 0.3)])
    line = tiny_line(trace, ws, pick_time=1.5)  # a grip so slow the other part gets away
    r = simulate(make_scenario(line), make_policy("SD"))
    kept = r.parts[r.parts["outcome"] == "picked"]
    lost = r.parts[r.parts["outcome"] == "missed"]
    assert len(kept) == 1 and len(lost) == 1
    assert kept["y"].iloc[0] == 0.3  # SD: the part nearest the upper edge (the bin side)
    assert lost["left_at"].iloc[0] == pytest.approx(ws[1] / V_B)  # left the last workspace
    assert r.kpis["gripping_rate"] == 50.0
    assert r.kpis["robots"][0]["lost"] == 1 and r.kpis["robots"][0]["passed_on"] == 0


@pytest.mark.parametrize("acc", [1.5, 4.0, 50.0])
def test_one_part_with_an_acceleration_limit(make_scenario, write_trace, tmp_path, acc) -> None:
    ws = (0.0, 0.6)
    trace = write_trace(tmp_path / "acc.csv", [(0.0, 0.05)])
    r = simulate(make_scenario(tiny_line(trace, ws, acceleration=acc)), make_policy("SD"))
    p = r.parts.iloc[0]
    assert p["outcome"] == "picked" and p["decided_at"] == 0.0
    bx, by = base_of(ws)
    t = intercept_time(0.0 - bx, 0.05 - by, V_B, V_R, acc)
    plain = intercept(0.0, 0.05, base_of(ws))
    assert t > plain  # ramps make the approach longer
    assert p["picked_at"] == pytest.approx(t, abs=1e-12)
    # the trapezoidal move to the meeting point takes exactly T (to the solver's precision)
    hit = (V_B * t, 0.05)
    assert move_time(math.dist(hit, (bx, by)), V_R, acc) == pytest.approx(t, abs=1e-9)
    placed = t + PICK + move_time(math.dist(hit, bin_of(ws)), V_R, acc) + PLACE
    assert p["placed_at"] == pytest.approx(placed, abs=1e-12)


def test_fixed_arrivals_feed_one_part_per_gap(make_scenario) -> None:
    line = {
        "feeder": {"arrival": "fixed", "rate": 0.25},
        "robots": {"count": 1, "workspaces": [[0.0, 0.6]]},
        "duration": 10.0,
        "warmup": 0.0,
    }
    r = simulate(make_scenario(line), make_policy("SD"))
    assert r.parts["fed_at"].tolist() == [0.0, 4.0, 8.0]
    assert (r.parts["outcome"] == "picked").all()
    assert (r.parts["decided_at"] == r.parts["fed_at"]).all()  # an idle robot takes each part


def test_an_unreachable_part_never_freezes_the_clock(make_scenario, guarded, tmp_path) -> None:
    # Arm 0.7 m/s against a 0.6 m/s belt, a 0.1 m workspace: a part on the lower edge is
    # never interceptable inside it. The grid of 1 cell makes the robot look only when a
    # part reaches x = a. It must see the part go by (missed) for every feeding time.
    ws = (0.3, 0.4)
    for k in range(1, 60):
        fed = round(0.01 * k, 2)
        trace = tmp_path / f"t{k}.csv"
        trace.write_text(f"time,y\n{fed},0.0\n", encoding="utf-8")
        line = {
            "belt": {"length": 1.0, "width": WIDTH, "speed": 0.6, "grid": [1, 8]},
            "feeder": {"arrival": "trace", "trace": str(trace)},
            "robots": {"count": 1, "workspaces": [list(ws)], "arm_speed": 0.7},
            "duration": 2.0,
            "warmup": 0.0,
        }
        # before the fix of Belt.next_entry, 18 of these 59 runs froze the clock (0 s NooPs)
        r = guarded(make_scenario(line), make_policy("SD"))
        assert r.parts["outcome"].tolist() == ["missed"], fed
        assert r.parts["left_at"].iloc[0] == pytest.approx(fed + ws[1] / 0.6)
