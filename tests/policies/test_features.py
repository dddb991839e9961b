"""Decision features of the lookahead's students: ``student-v2`` (compiled) keeps every value of
``student-v1`` (the Python reference), is the same on both engines, stays in the numpy forward
pass's non-negative range, and its second-pick values are what the geometry says; ``student-v3``
and ``-v4`` add continuations whose grip counts follow from the geometry."""

from __future__ import annotations

import math

import numpy as np
import pytest

from pnp_twin.policies.hdqn import continuation as cont
from pnp_twin.policies.hdqn import features_compiled as fc
from pnp_twin.policies.hdqn.features import DecisionFeatures, size
from pnp_twin.policies.rules import RULES
from pnp_twin.twin.decision import Decision
from pnp_twin.twin.geometry import intercept_time, move_time
from pnp_twin.twin.loader import load_scenario, with_overrides
from pnp_twin.twin.run import simulate

R = ["FIFO", "LIFO", "SD", "LD", "SPT"]
N = 4


class Probe:
    """Follows SD and records feature sets (``student-v1`` and ``-v2`` unless named) and the
    rules' picks at every decision: rows of (vector per set..., picks, candidates)."""

    name = "probe"

    def __init__(self, *names: str) -> None:
        self.sets = [DecisionFeatures(n, R) for n in names or ("student-v1", "student-v2")]
        self.rows: list[tuple] = []  # type: ignore[type-arg]
        self.last_rule = "SD"

    def reset(self, robots, rng) -> None:  # type: ignore[no-untyped-def]
        for f in self.sets:
            f.reset(robots, 10.0)

    def attach(self, belt) -> None:  # type: ignore[no-untyped-def]
        for f in self.sets:
            f.attach(belt)

    def choose(self, decision: Decision) -> int:
        picks = self.sets[0].picks(decision)
        row = tuple(f.vector(decision, picks) for f in self.sets)
        self.rows.append((*row, picks, len(decision)))
        return RULES["SD"](decision, np.random.default_rng(0))


def probe(engine: str, scenario: str = "paper_baseline") -> Probe:
    p = Probe()
    line = with_overrides(load_scenario(scenario), {"duration": 30.0, "warmup": 0.0})
    simulate(line, p, seed=5, engine=engine)
    assert len(p.rows) > 50
    return p


@pytest.mark.parametrize("scenario", ["paper_baseline", "breakdowns"])
def test_v2_keeps_v1_and_is_the_same_on_both_engines(scenario: str) -> None:
    fast, simpy = probe("fast", scenario), probe("simpy", scenario)
    assert len(fast.rows) == len(simpy.rows)
    picks_end = N + fc.PER_PICK * len(R)
    line_end = picks_end + fc.PER_ROBOT * N + 3
    for (v1, v2, _, _), (_, w2, _, _) in zip(fast.rows, simpy.rows, strict=True):
        np.testing.assert_array_equal(v2, w2)
        assert v2.shape == (size("student-v2", len(R), N),) and v2.dtype == np.float32
        per_pick = v2[N:picks_end].reshape(len(R), fc.PER_PICK)[:, :7].ravel()
        again = np.concatenate([v2[:N], per_pick, v2[picks_end:line_end]])
        np.testing.assert_array_equal(again, v1)


def test_v2_values_are_bounded_and_say_what_they_mean() -> None:
    n_rules = len(R)
    picks_end = N + fc.PER_PICK * n_rules
    slots = picks_end + fc.PER_ROBOT * N + 3
    for _, v2, picks, m in probe("fast").rows:
        assert np.isfinite(v2).all() and (v2 >= 0.0).all()  # the numpy forward's bound
        blocks = v2[N:picks_end].reshape(n_rules, fc.PER_PICK)
        # a second part is placed after the first is back at the bin
        back, second = blocks[:, 3], 2.0 * blocks[:, 7]
        assert (second >= np.minimum(back, fc.HORIZON) - 1e-6).all()
        shown = v2[slots : slots + fc.PER_SLOT * fc.SLOTS].reshape(fc.SLOTS, fc.PER_SLOT)
        assert shown[:, 3].sum() == min(m, fc.SLOTS)  # candidates present
        chosen = v2[slots + fc.PER_SLOT * fc.SLOTS :][: n_rules * fc.SLOTS]
        chosen = chosen.reshape(n_rules, fc.SLOTS)
        for r, k in enumerate(picks):
            assert chosen[r].sum() == (k < fc.SLOTS) and (k >= fc.SLOTS or chosen[r, k] == 1.0)


def test_second_pick_follows_the_geometry() -> None:
    # one robot on [0, 1] m, bin at (0.5, 1), arm 2 m/s, grip and release 0.1 s each
    me = np.array([0.0, 1.0, 0.5, 1.0, 2.0, 0.0, 0.1, 0.1])
    v, back = 0.1, 0.5
    xs, ys = np.array([0.5, 0.2]), np.array([0.5, 0.5])
    none = np.zeros(0)
    best, count = fc._second(0, back, me, v, xs, ys, none, none, 4.0)
    x = 0.2 + v * back
    t = intercept_time(x - 0.5, 0.5 - 1.0, v, 2.0, 0.0)
    gx = x + v * t
    want = back + t + 0.2 + move_time(math.hypot(0.5 - gx, 0.5), 2.0, 0.0)
    assert count == 1 and best == pytest.approx(want, abs=1e-12)
    # a part upstream counts too, and the sooner one wins
    best2, count2 = fc._second(0, back, me, v, xs, ys, np.array([0.45]), np.array([0.9]), 4.0)
    assert count2 == 2 and best2 < best
    # a part gone past the workspace by then is no option: nothing left, the horizon
    assert fc._second(0, 9.0, me, v, xs, ys, none, none, 4.0) == (4.0, 0)
    # still reachable but finished after the horizon: counted, capped at the horizon
    assert fc._second(0, 6.0, me, v, xs, ys, none, none, 4.0) == (4.0, 1)


def _line(busy1: float, claimed: bool = False, long: bool = False) -> tuple[int, int, int]:
    """Robot 0 on [0, 1] m takes part A (x 0.5); robot 1 on [1, 2] m, free in ``busy1`` s;
    part B (x 0.3) is upstream in robot 0's workspace, part C (x 1.2) in robot 1's; the
    belt runs at 0.1 m/s, arms at 2 m/s, grip and release take 0.05 s each. The short
    continuation, or with ``long`` the long one (until every part has passed x = 2 m)."""
    robots = np.array(
        [[0.0, 1.0, 0.5, 1.0, 2.0, 0.0, 0.05, 0.05], [1.0, 2.0, 1.5, 1.0, 2.0, 0.0, 0.05, 0.05]]
    )
    v = 0.1
    _, first = _first_cycle(v)
    px, py = np.array([1.2, 0.5, 0.3]), np.full(3, 0.5)  # in the order they were fed
    taken = np.array([0.0, 0.0, 1.0 if claimed else 0.0])
    free = np.array([0.0, busy1])
    if long:
        limits = (2.0 / v, math.inf, cont.LONG_STEPS)
    else:
        limits = (cont.HORIZON, cont.HORIZON, cont.STEPS)
    return cont._continue(0, 1, first, robots, v, px, py, taken, free, *limits)


def _first_cycle(v: float) -> tuple[float, float]:
    """Robot 0 taking A: its interception time, and when it is back at its bin."""
    t_a = intercept_time(0.0, -0.5, v, 2.0, 0.0)
    gx = 0.5 + v * t_a
    return t_a, t_a + 0.1 + move_time(math.hypot(0.5 - gx, 0.5), 2.0, 0.0)


def test_continuation_counts_the_grips_the_geometry_allows() -> None:
    v = 0.1
    _, back = _first_cycle(v)
    xb = 0.3 + v * back  # B when robot 0 is back at its bin
    second_grip = back + intercept_time(xb - 0.5, -0.5, v, 2.0, 0.0)
    assert second_grip < cont.HORIZON  # so robot 0 grips B within the horizon
    # A (the decision), C by robot 1 at once, B by robot 0 after A
    assert _line(0.0) == (3, 1, 1)
    # robot 1 busy past the horizon: C is not gripped in it
    assert _line(2.0) == (2, 0, 1)
    # B claimed by another robot: nobody takes it
    assert _line(0.0, claimed=True) == (2, 1, 0)


def test_the_long_continuation_counts_each_parts_fate() -> None:
    # robot 1 busy for 2 s: C (8 s from the line's end) is gripped after the short
    # continuation's second, and the long one counts it, as the teacher does
    assert _line(2.0, long=True) == (3, 1, 1)
    assert _line(0.0, long=True) == (3, 1, 1)
    # robot 1 busy until C has passed x = 2 m: C is lost in both
    assert _line(9.0, long=True) == (2, 0, 1) == _line(9.0)


def test_v4_is_v3_plus_the_long_continuation_and_the_same_on_both_engines() -> None:
    rows = {}
    for engine in ("fast", "simpy"):
        p = Probe("student-v4", "student-v3", "student-v2")
        line = with_overrides(load_scenario("paper_baseline"), {"duration": 30.0, "warmup": 0.0})
        simulate(line, p, seed=5, engine=engine)
        rows[engine] = p.rows
    base, nr = size("student-v2", len(R), N), len(R)
    assert size("student-v3", nr, N) == base + cont.size(nr)
    assert size("student-v4", nr, N) == base + cont.size(nr, long=True) == base + 8 * nr
    spread = {"short": 0, "long": 0}
    for (v4, v3, v2, picks, _), (w4, w3, _, _, _) in zip(rows["fast"], rows["simpy"], strict=True):
        np.testing.assert_array_equal(v4, w4)
        np.testing.assert_array_equal(v3, w3)
        np.testing.assert_array_equal(v4[: len(v3)], v3)
        np.testing.assert_array_equal(v3[:base], v2)
        tails = v4[base:].reshape(2, nr, cont.PER_ROLL)
        assert (tails >= 0.0).all() and (tails <= 1.0).all()
        for name, tail in zip(spread, tails, strict=True):
            # rules picking the same part get the same values; the best pick's shortfall is 0
            for r, k in enumerate(picks):
                assert (tail[r] == tail[picks.index(k)]).all()
            assert tail[:, 3].min() == 0.0
            spread[name] += tail[:, 3].max() > 0.0
        # the long one plays the same picks on past the second: it counts no fewer grips
        short, long = tails[0, :, 0] * cont.SCALE_SHORT[0], tails[1, :, 0] * cont.SCALE_LONG[0]
        assert (long >= short - 1e-4).all()
    assert spread["short"] > 0 and spread["long"] > 0  # they tell some picks apart
