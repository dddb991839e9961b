"""twin.geometry: move times (plain and trapezoidal), interception, tool positions."""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from pnp_twin.twin.geometry import intercept_time, move_time, position_along, workspaces


def quadratic_intercept(dx: float, dy: float, vb: float, vr: float) -> float:
    """Smallest T >= 0 with (dx + vb T)^2 + dy^2 = (vr T)^2, from the polynomial's roots."""
    roots = np.roots([vr * vr - vb * vb, -2.0 * dx * vb, -(dx * dx + dy * dy)])
    real = [r.real for r in roots if abs(r.imag) < 1e-12 and r.real >= -1e-12]
    return max(min(real), 0.0)


def trapezoid_time(d: float, v: float, a: float) -> float:
    """Rest-to-rest time over d with top speed v and acceleration a, from kinematics."""
    t_ramp = v / a  # time to reach top speed
    d_ramps = 2 * (0.5 * a * t_ramp**2)  # distance accelerating plus braking
    if d >= d_ramps:
        return 2 * t_ramp + (d - d_ramps) / v
    return 2 * math.sqrt((d / 2) / (0.5 * a))  # triangle: accelerate half way, brake half


def test_move_time_without_acceleration_is_distance_over_speed() -> None:
    assert move_time(1.5, 3.0) == pytest.approx(0.5)
    assert move_time(0.0, 3.0) == 0.0


@pytest.mark.parametrize("d", [0.0, 0.01, 0.2, 0.45, 0.5, 1.0, 3.0])
def test_trapezoidal_move_time_matches_kinematics(d: float) -> None:
    # v = 3 m/s, a = 18 m/s^2: the ramps take 0.5 m, so 0.01..0.45 are triangles
    assert move_time(d, 3.0, 18.0) == pytest.approx(trapezoid_time(d, 3.0, 18.0), abs=1e-12)


def test_acceleration_only_slows_moves() -> None:
    for d in (0.05, 0.3, 2.0):
        assert move_time(d, 3.0, 10.0) > move_time(d, 3.0)
    # a huge acceleration is the instantaneous case in the limit
    assert move_time(1.0, 3.0, 1e9) == pytest.approx(move_time(1.0, 3.0), abs=1e-6)


@pytest.mark.parametrize(
    ("dx", "dy"), [(-0.3, 0.1), (0.2, -0.15), (0.0, 0.2), (-0.5, 0.0), (0.4, 0.0), (0.0, 0.0)]
)
def test_intercept_closed_form_solves_the_quadratic(dx: float, dy: float) -> None:
    vb, vr = 0.8, 3.0
    t = intercept_time(dx, dy, vb, vr)
    assert t == pytest.approx(quadratic_intercept(dx, dy, vb, vr), abs=1e-12)
    assert t >= 0.0
    # the tool, moving straight at vr, meets the part where it is after t
    assert math.hypot(dx + vb * t, dy) == pytest.approx(vr * t, abs=1e-12)


def test_intercept_of_a_part_upstream_happens_before_the_part_reaches_the_tool() -> None:
    # part 0.3 m upstream on the tool's line: the tool and the part close at vr + vb
    assert intercept_time(-0.3, 0.0, 0.8, 3.0) == pytest.approx(0.3 / 3.8)
    # part 0.3 m downstream: the tool chases it at vr - vb
    assert intercept_time(0.3, 0.0, 0.8, 3.0) == pytest.approx(0.3 / 2.2)


@settings(max_examples=40, deadline=None)
@given(
    dx=st.floats(-1.0, 1.0),
    dy=st.floats(-0.6, 0.6),
    vb=st.floats(0.2, 1.2),
    ratio=st.floats(1.3, 6.0),
    acc=st.floats(2.0, 60.0),
)
def test_trapezoidal_intercept_is_the_earliest_meeting(
    dx: float, dy: float, vb: float, ratio: float, acc: float
) -> None:
    vr = vb * ratio
    t = intercept_time(dx, dy, vb, vr, acc)
    plain = intercept_time(dx, dy, vb, vr)
    assert t >= plain - 1e-12  # acceleration never helps

    def late(tt: float) -> float:  # how late the tool is at the part's position at tt
        return trapezoid_time(math.hypot(dx + vb * tt, dy), vr, acc) - tt

    assert late(t) <= 1e-9  # the tool is there in time
    # ... and no earlier instant works (checked on a fine grid below t)
    grid = np.linspace(0.0, t, 200, endpoint=False)
    assert all(late(float(tt)) > -1e-9 for tt in grid[:-1])


def test_position_along_endpoints_and_midpoint() -> None:
    start, end = (0.0, 0.0), (0.6, 0.8)  # 1 m
    assert position_along(start, end, 0.0, 2.0) == pytest.approx(start)
    assert position_along(start, end, 0.25, 2.0) == pytest.approx((0.3, 0.4))
    assert position_along(start, end, 5.0, 2.0) == end
    # trapezoid: symmetric, so halfway in time is halfway in distance
    total = move_time(1.0, 2.0, 8.0)
    assert position_along(start, end, total / 2, 2.0, 8.0) == pytest.approx((0.3, 0.4))
    # still accelerating after 0.1 s: s = a t^2 / 2 = 0.04 m
    x, y = position_along(start, end, 0.1, 2.0, 8.0)
    assert math.hypot(x, y) == pytest.approx(0.04)


def test_workspaces_are_laid_out_with_the_gap_between_them() -> None:
    # three 0.5 m workspaces from x = 0.3, 0.1 m apart, written out by hand
    expected = [(0.3, 0.8), (0.9, 1.4), (1.5, 2.0)]
    assert np.allclose(workspaces(3, 0.3, 0.5, 0.1), expected, rtol=0, atol=1e-12)
    no_gap = [(0.3, 0.8), (0.8, 1.3), (1.3, 1.8)]
    assert np.allclose(workspaces(3, 0.3, 0.5, 0.0), no_gap, rtol=0, atol=1e-12)
    # explicit bounds are taken as given, whatever the gap
    assert workspaces(2, 0.0, 1.0, 0.3, [(0.1, 0.4), (0.5, 0.7)]) == [(0.1, 0.4), (0.5, 0.7)]


def test_a_run_picks_only_inside_the_gapped_workspaces(make_scenario: Callable[..., Any]) -> None:
    from pnp_twin.policies.registry import make_policy
    from pnp_twin.twin import simulate

    sc = make_scenario(robots__count=3, robots__workspace_gap=0.1, duration=20.0)
    bounds = [(0.3, 0.8), (0.9, 1.4), (1.5, 2.0)]  # by hand, not from twin.geometry
    assert np.allclose(sc.robots.layout(), bounds, rtol=0, atol=1e-12)
    res = simulate(sc, make_policy("SD"), seed=3)
    parts, v = res.parts, sc.belt.speed
    picked = parts[parts["outcome"] == "picked"]
    x = v * (picked["picked_at"] - picked["fed_at"])
    for r, (a, b) in enumerate(bounds, start=1):
        mine = x[picked["robot"] == r]
        assert len(mine) > 0 and mine.between(a - 1e-9, b + 1e-9).all(), r
    # a part no robot picked leaves the last workspace at x = 2.0 (1.8 without the gaps)
    missed = parts[parts["outcome"] == "missed"]
    assert len(missed) > 0
    assert np.allclose(missed["left_at"], missed["fed_at"] + 2.0 / v, rtol=0, atol=1e-9)


def test_a_part_running_into_a_waiting_tool_is_met_when_it_arrives_at_the_latest() -> None:
    """With an acceleration limit the tool may simply wait where the part passes: a part
    0.0625 m upstream, on the tool's line, at 0.5 m/s reaches it after 0.125 s, so the
    earliest meeting is no later (stepping used to jump over that window); both engines."""
    from pnp_twin.twin.fast import mathlib

    t = intercept_time(-0.0625, 0.0, 0.5, 1.0, 2.0)
    assert t <= 0.125 + 1e-12
    assert t == mathlib.intercept_time(-0.0625, 0.0, 0.5, 1.0, 2.0)
    x = -0.0625 + 0.5 * t  # where the part is then: the tool gets there in time
    assert trapezoid_time(abs(x), 1.0, 2.0) <= t + 1e-9
