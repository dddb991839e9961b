"""The KPIs of hand-built record tables (turned into the KPIs' arrays), worked out by hand."""

from __future__ import annotations

import json
import math

import numpy as np
import pandas as pd
import pytest

from pnp_twin.policies import make_policy
from pnp_twin.twin import simulate
from pnp_twin.twin.decision import RobotSpec
from pnp_twin.twin.kpis import flat_kpis, table_kpis
from pnp_twin.twin.line import robot_specs
from pnp_twin.twin.records import PART_COLUMNS, SPAN_COLUMNS

NAN = math.nan
WARMUP, DURATION = 10.0, 20.0  # the window is [10, 20): 10 s


def spec(i: int, a: float, b: float) -> RobotSpec:
    # bin 0.2 m beyond the upper edge, arm 2 m/s, grip and release 0.1 s: the shortest cycle
    # is 0.1 + 0.1 + 2 * 0.2 / 2 = 0.4 s, a capacity of 2.5 picks/s
    return RobotSpec(i, 2, (a, b), ((a + b) / 2, 0.6), 2.0, 0.0, 0.1, 0.1, 0.8, 0.4)


SPECS = [spec(0, 0.3, 0.8), spec(1, 0.8, 1.3)]


def parts_table() -> pd.DataFrame:
    rows = [
        # part fed   y    kind outcome  robot rule   decided picked placed blocked left
        (0, 5.0, 0.2, "", "picked", 1, "SD", 5.5, 5.8, 6.5, 0.0, 5.8),  # before the window
        (1, 10.0, 0.3, "", "picked", 1, "SD", 11.0, 11.5, 12.0, 0.2, 11.5),
        (2, 11.0, 0.1, "", "picked", 2, "FIFO", 12.0, 12.4, 13.0, 0.0, 12.4),
        (3, 12.0, 0.2, "", "missed", None, None, NAN, NAN, NAN, 0.0, 13.625),
        (4, 13.0, 0.25, "", "picked", 1, "SD", 19.0, 19.5, 21.0, 0.0, 19.5),  # ends late
        (5, 20.0, 0.2, "", "missed", None, None, NAN, NAN, NAN, 0.0, 21.625),  # after it
    ]
    df = pd.DataFrame(rows, columns=PART_COLUMNS)
    df["robot"] = df["robot"].astype("Int64")
    return df


def spans_table() -> pd.DataFrame:
    rows = [
        (1, "wait", 0.0, 10.5),  # 0.5 s inside the window
        (2, "noop", 9.0, 9.5),  # before the window: neither time nor a NooP decision
        (2, "noop", 10.0, 12.0),
        (1, "blocked", 11.8, 12.0),  # a box change inside part 1's cycle
        (2, "interrupted", 13.0, 13.5),  # an approach cut short: busy time, no pick
        (2, "down", 14.0, 16.0),
    ]
    return pd.DataFrame(rows, columns=SPAN_COLUMNS)


@pytest.fixture()
def kpis() -> dict:
    return table_kpis(parts_table(), spans_table(), SPECS, WARMUP, DURATION)


def test_gripping_rate_counts_parts_fed_in_the_window(kpis) -> None:
    # parts 1-4 were fed in [10, 20); 1, 2 and 4 were picked
    assert kpis["parts_presented"] == 4
    assert kpis["parts_picked"] == 3
    assert kpis["parts_missed"] == 1
    assert kpis["gripping_rate"] == pytest.approx(75.0)


def test_throughput_flow_and_efficiency(kpis) -> None:
    assert kpis["throughput"] == pytest.approx(0.3)  # 3 picks in 10 s
    assert kpis["part_flow"] == pytest.approx(0.4)  # 4 parts presented in 10 s
    # maximum = min(flow 0.4, measured cycle rates: 2 picks in 1.8 s busy, 1 in 1.5 s)
    assert kpis["max_throughput"] == pytest.approx(0.4)
    assert kpis["efficiency"] == pytest.approx(0.75)
    assert [r["capacity"] for r in kpis["robots"]] == pytest.approx([2 / 1.8, 1 / 1.5])
    assert [r["nominal_capacity"] for r in kpis["robots"]] == pytest.approx([2.5, 2.5])
    assert [r["picks"] for r in kpis["robots"]] == [2, 1]
    assert [r["throughput"] for r in kpis["robots"]] == pytest.approx([0.2, 0.1])


def test_utilisation_and_state_shares(kpis) -> None:
    r1, r2 = kpis["robots"]
    # robot 1 busy: 11-12 (less 0.2 s blocked) and 19-20 (clipped at the window's end)
    assert r1["utilisation"] == pytest.approx((1.0 - 0.2 + 1.0) / 10)
    assert r1["blocked"] == pytest.approx(0.02)
    assert r1["wait"] == pytest.approx(0.05)
    assert (r1["noop"], r1["down"], r1["availability"]) == (0.0, 0.0, 1.0)
    # robot 2 busy: 12-13 and the interrupted approach 13-13.5; NooP 10-12; down 14-16
    assert r2["utilisation"] == pytest.approx(1.5 / 10)
    assert r2["noop"] == pytest.approx(0.2)
    assert r2["down"] == pytest.approx(0.2)
    assert r2["availability"] == pytest.approx(0.8)
    assert r2["wait"] == 0.0 and r2["blocked"] == 0.0
    assert kpis["utilisation"] == pytest.approx((1.8 + 1.5) / 20)


def test_unpicked_parts_are_passed_on_or_lost(kpis) -> None:
    # part 2 left robot 1's workspace and robot 2 picked it: passed on; part 3 passed both
    # workspaces and reached the return conveyor: lost (issue 10, item 6)
    assert [r["passed_on"] for r in kpis["robots"]] == [1, 0]
    assert [r["lost"] for r in kpis["robots"]] == [1, 1]
    assert kpis["parts_missed"] == 1
    assert "missed" not in kpis["robots"][0]
    assert [r["workspace"] for r in kpis["robots"]] == [[0.3, 0.8], [0.8, 1.3]]


def test_cycle_times(kpis) -> None:
    # picked parts of the window: cycles 1 s, 1 s and 2 s (decided to placed)
    assert kpis["cycle_time_mean"] == pytest.approx(4 / 3)
    assert kpis["cycle_time_p50"] == pytest.approx(1.0)
    assert kpis["cycle_time_p95"] == pytest.approx(1.9)  # linear interpolation
    assert kpis["cycle_time_max"] == pytest.approx(2.0)
    assert [r["cycle_time_mean"] for r in kpis["robots"]] == pytest.approx([1.5, 1.0])


def test_decisions_per_rule(kpis) -> None:
    # picks of the window by rule, and NooPs that started in the window
    assert kpis["decisions"] == {"FIFO": 1, "NooP": 1, "SD": 2}


def test_flat_row(kpis) -> None:
    row = flat_kpis(kpis)
    assert row["gripping_rate"] == pytest.approx(75.0)
    assert row["r1_picks"] == 2 and row["r2_picks"] == 1
    assert row["r2_availability"] == pytest.approx(0.8)
    assert row["r1_passed_on"] == 1 and row["r1_lost"] == 1
    assert (row["rule_SD"], row["rule_FIFO"], row["rule_NooP"]) == (2, 1, 1)
    assert not any(isinstance(v, dict | list) for v in row.values())
    assert "robots" not in row and "decisions" not in row


def test_an_empty_window_gives_nan_rates_not_errors() -> None:
    parts = parts_table().iloc[[0]]  # only a part fed before the window
    k = table_kpis(parts, spans_table().iloc[:0], SPECS, WARMUP, DURATION)
    assert k["parts_presented"] == 0
    assert math.isnan(k["gripping_rate"]) and math.isnan(k["cycle_time_mean"])
    assert k["throughput"] == 0.0
    assert k["decisions"] == {"NooP": 0}


def test_a_pick_without_a_rule_name_counts_as_question_mark() -> None:
    parts = parts_table()
    parts.loc[2, "rule"] = None  # robot 2's pick of part 2
    k = table_kpis(parts, spans_table(), SPECS, WARMUP, DURATION)
    assert k["decisions"] == {"?": 1, "NooP": 1, "SD": 2}


def test_a_run_and_its_tables_give_the_same_kpis(make_scenario) -> None:
    # the SimPy run computes its KPIs from the Recorder's arrays, not from its tables: the
    # tables read back must give the same figures (bit for bit); breakdowns, box changes
    # and t_any included so spans of every state occur
    changes = {"robots.mtbf": 20.0, "robots.mttr": 2.0, "bins.capacity": 5}
    states: set[str] = set()
    for scheme in ("t_any", "t_all"):  # t_any interrupts approaches, t_all makes robots wait
        sc = make_scenario({**changes, "termination": scheme, "bins.change_time": 1.0})
        r = simulate(sc, make_policy("SIRO"))
        states |= set(r.spans["state"])
        w0, w1 = r.kpis["window"]
        ref = table_kpis(r.parts, r.spans, robot_specs(sc), w0, w1)
        got = {k: v for k, v in r.kpis.items() if k in ref}
        assert list(got) == list(ref)
        assert json.dumps(got) == json.dumps(ref)
    assert states == {"wait", "interrupted", "noop", "blocked", "down"}


def test_kpis_of_a_real_run_are_consistent(make_scenario) -> None:
    r = simulate(make_scenario(), make_policy("SPT"))
    k = r.kpis
    span = r.scenario.duration - r.scenario.warmup
    assert sum(x["picks"] for x in k["robots"]) == k["parts_picked"]
    assert k["throughput"] == pytest.approx(k["parts_picked"] / span)
    assert k["decisions"]["SPT"] == k["parts_picked"]
    for x in k["robots"]:
        shares = [x[s] for s in ("utilisation", "noop", "wait", "blocked", "down")]
        assert all(s >= 0.0 for s in shares)
        assert sum(shares) <= 1.0 + 1e-9  # a robot is in one state at a time
    # the decisions table counts every choice and NooP of the whole run
    d = r.decisions
    spt = int(d.loc[d["rule"] == "SPT", "count"].sum())
    assert spt == int((r.parts["outcome"] == "picked").sum())
    # every NooP decision has its span, but for the one each robot is in when the run stops
    noop_decisions = int(d.loc[d["rule"] == "NooP", "count"].sum())
    noop_spans = int((r.spans["state"] == "noop").sum())
    assert noop_spans <= noop_decisions <= noop_spans + r.scenario.robots.count
    assert np.isfinite(k["cycle_time_mean"])


def test_a_saturated_line_reads_near_full_efficiency(make_scenario) -> None:
    # far more parts than the robots can take: never idle, so efficiency ~ utilisation ~ 100 %
    # (the nominal shortest-cycle capacity read 73 % on such a line: issue 10, item 7)
    sc = make_scenario({"feeder.rate": 30.0})
    k = simulate(sc, make_policy("SPT")).kpis
    assert k["utilisation"] > 0.97
    assert k["efficiency"] == pytest.approx(k["utilisation"], abs=0.02)
    assert 0.95 < k["efficiency"] <= 1.0


def test_a_repair_outlasting_the_run_counts_as_down_time(make_scenario) -> None:
    # fixed MTBF 100 s, MTTR 1000 s: robot 1 breaks at its first decision after t = 100 s and
    # is still down when the run ends; it used to read availability 1.0 (issue 10, item 3)
    sc = make_scenario(
        {
            "robots.count": 1,
            "robots.mtbf": 100.0,
            "robots.mttr": 1000.0,
            "robots.failure_distribution": "fixed",
            "duration": 300.0,
            "warmup": 0.0,
        }
    )
    r = simulate(sc, make_policy("SPT"))
    robot = r.kpis["robots"][0]
    assert robot["down"] == pytest.approx(2 / 3, abs=0.01)
    assert robot["availability"] == pytest.approx(1 / 3, abs=0.01)
    down = r.spans[r.spans["state"] == "down"]
    assert len(down) == 1 and down["end"].iloc[0] == pytest.approx(r.sim_time)


def test_record_tables_number_robots_from_1(make_scenario) -> None:
    # --events, --spans and the study records are read by people: robot 1 is the first
    r = simulate(make_scenario(), make_policy("SPT"))
    n = r.scenario.robots.count
    picked = r.parts[r.parts["outcome"] == "picked"]
    assert set(picked["robot"].astype(int)) <= set(range(1, n + 1))
    assert 1 in set(picked["robot"].astype(int))
    assert set(r.spans["robot"]) <= set(range(1, n + 1)) and 1 in set(r.spans["robot"])
    assert set(r.decisions["robot"]) == set(range(1, n + 1))


def test_efficiency_never_passes_one_by_rounding() -> None:
    # four robots busy all of a 95 s window: capacity = throughput for each, so the exact
    # efficiency is 1; summing the four capacities rounds 1 ulp below the throughput
    from pnp_twin.twin.kpis import STATES, WELCH_BINS, KpiTally, tally_kpis

    picks = np.array([1130, 115, 1541, 1472])
    span = 95.0
    assert float((picks / span).sum()) < picks.sum() / span  # the rounding this is about
    states = np.zeros((4, len(STATES)))
    states[:, 0] = span
    cycles = np.full(int(picks.sum()), 0.3)
    sums = KpiTally(
        presented=10_000,
        picked=int(picks.sum()),
        picks=picks,
        states=states,
        cycles=cycles,
        robot_cycles=cycles,
        robot_starts=np.concatenate([[0], np.cumsum(picks)]),
        rules=np.array([0, int(picks.sum())]),
        noops=0,
        welch_parts=np.zeros(WELCH_BINS, dtype=np.int64),
        welch_picked=np.zeros(WELCH_BINS),
    )
    specs = [spec(i, 0.3 + 0.5 * i, 0.8 + 0.5 * i) for i in range(4)]
    k = tally_kpis(sums, ["SD"], specs, 0.0, span)
    assert k["max_throughput"] < k["throughput"]  # by one ulp
    assert k["efficiency"] == 1.0
