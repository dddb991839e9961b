"""The fast engine's event calendar on many robots, its compiled KPI pass, and the one plan
of the line that both engines read (issue 17)."""

from __future__ import annotations

import numpy as np
import pytest

from pnp_twin.policies import make_policy
from pnp_twin.twin import simulate
from pnp_twin.twin.fast import layout as L
from pnp_twin.twin.fast.engine import FastLine
from pnp_twin.twin.kpis import compute_kpis
from pnp_twin.twin.line import Line
from pnp_twin.twin.loader import load_scenario
from pnp_twin.twin.plan import LinePlan, reach_margin


def _wide(robots: int, scheme: str, rate: float = 10.0):  # type: ignore[no-untyped-def]
    return load_scenario(
        "paper_baseline",
        {
            "duration": 20.0,
            "warmup": 2.0,
            "termination": scheme,
            "robots.count": robots,
            "belt.length": round(0.3 + robots * 0.2192 + 0.1, 4),
            "feeder.rate": rate,
        },
    )


@pytest.mark.parametrize(
    ("robots", "scheme", "rule"),
    [(64, "t_continue", "SD"), (33, "t_any", "SIRO"), (17, "t_all", "SPT"), (5, "t_any", "LD")],
)
def test_many_robots_give_the_simpy_events(robots: int, scheme: str, rule: str) -> None:
    """The calendar (a loser tree, widths not a power of two included) orders wake-ups as
    SimPy's queue does: same part records, spans, decisions and KPIs."""
    sc = _wide(robots, scheme, rate=10.0 * robots / 8)
    a = simulate(sc, make_policy(rule, robots), seed=5, engine="simpy")
    b = simulate(sc, make_policy(rule, robots), seed=5, engine="fast")
    for table in ("parts", "spans", "decisions"):
        assert getattr(a, table).equals(getattr(b, table)), table
    assert repr(a.kpis) == repr(b.kpis)


def test_the_compiled_kpi_pass_equals_the_numpy_one() -> None:
    """FastLine.kpis (one compiled pass) and compute_kpis of its records (numpy) agree."""
    for name, rule in [("breakdowns", "SIRO"), ("rule_mix", "SPT"), ("two_robot", "LIFO")]:
        sc = load_scenario(name, {"termination": "t_any", "bins.capacity": 3})
        line = FastLine(sc, make_policy(rule, sc.robots.count), seed=2)
        line.run()
        got = line.kpis(sc.warmup)
        want = compute_kpis(*line.kpi_records(), line.specs, sc.warmup, line.duration)
        assert repr(got) == repr(want)


def test_both_engines_read_one_plan() -> None:
    """The derived constants come from the plan: the SimPy robots' margins and bases and the
    kernel's parameters are the plan's doubles; the run ends where the plan says."""
    sc = _wide(6, "t_continue")
    plan = LinePlan.of(sc, seed=3)
    line = Line(sc, make_policy("SD", 6), seed=3)
    fast = FastLine(sc, make_policy("SD", 6), seed=3)
    assert line.plan == plan == fast.plan
    assert line.end_at == fast.end_at == plan.end_at
    for robot, rp in zip(line.robots, plan.robots, strict=True):
        assert robot.x_lo == rp.x_lo == reach_margin(rp.spec)
        assert robot.base == rp.base
    np.testing.assert_array_equal(fast.fp[:, L.XLO], [rp.x_lo for rp in plan.robots])
    assert fast.gp[L.TICK] == plan.tick == line.belt.tick
    np.testing.assert_array_equal(fast.fed, line.belt.fed)


def test_span_buffer_grows_in_place_from_a_small_guess() -> None:
    """A first guess of a few spans grows (in place, by the run's rate) to the same spans."""
    sc = _wide(12, "t_continue")
    whole = FastLine(sc, make_policy("SD", 12), seed=1)
    whole.run()
    small = FastLine(sc, make_policy("SD", 12), seed=1)
    small.start(16, *small._rooms()[1:])
    assert small.advance(small.end_at) == 0 and small.finish() == 0
    k = int(whole.gs[L.NSPANS])
    assert int(small.gs[L.NSPANS]) == k and len(small.sp_i) >= k
    np.testing.assert_array_equal(small.sp_i[:k], whole.sp_i[:k])
    np.testing.assert_array_equal(small.sp_f[:k], whole.sp_f[:k])
