"""twin.geometry: move times (plain and trapezoidal), interception, tool positions."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from pnp_twin.twin.geometry import intercept_time, move_time, position_along


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
