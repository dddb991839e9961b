"""Summaries (t-intervals, paired differences, best policy) and sizing answers."""

from __future__ import annotations

import json
import math

import numpy as np
import pandas as pd
import pytest

from pnp_twin.studies import Options
from pnp_twin.studies.sizing import COUNT, MTBF, analyse, run_size, sizing_setup
from pnp_twin.studies.summary import (
    best_policies,
    paired_differences,
    summarise,
)
from pnp_twin.twin import load_scenario, with_overrides
from pnp_twin.twin.stats import t_interval, t_quantile


def test_t_quantiles_match_tables():
    for df, q in [(1, 12.7062), (2, 4.3027), (4, 2.7764), (9, 2.2622), (30, 2.0423)]:
        assert t_quantile(0.975, df) == pytest.approx(q, abs=1e-4)
    assert t_quantile(0.95, 4) == pytest.approx(2.1318, abs=1e-4)
    assert t_quantile(0.025, 4) == pytest.approx(-2.7764, abs=1e-4)


def test_t_interval_by_hand():
    mean, low, high = t_interval([1.0, 2.0, 3.0, 4.0, 5.0])
    half = 2.776445 * math.sqrt(2.5) / math.sqrt(5)  # t(0.975, 4) * s / sqrt(n)
    assert mean == 3.0
    assert low == pytest.approx(3.0 - half, abs=1e-5) and high == pytest.approx(
        3.0 + half, abs=1e-5
    )
    assert t_interval([7.0, 7.0, 7.0]) == (7.0, 7.0, 7.0)
    m, lo, hi = t_interval([5.0])
    assert m == 5.0 and math.isnan(lo) and math.isnan(hi)


def hand_table() -> pd.DataFrame:
    """Two points x two policies x three replications, with known numbers."""
    g = {
        (0, "A"): [80.0, 82.0, 84.0],
        (0, "B"): [81.0, 84.0, 87.0],  # B - A = 1, 2, 3: paired diff mean 2, sd 1
        (1, "A"): [90.0, 90.0, 90.0],
        (1, "B"): [70.0, 75.0, 80.0],
    }
    rows = []
    for (p, pol), values in g.items():
        for k, v in enumerate(values):
            rows.append(
                {
                    "point": p,
                    "x": [1, 2][p],
                    "policy": pol,
                    "replication": k,
                    "gripping_rate": v,
                    "throughput": v / 10,
                    "efficiency": v / 100,
                    "utilisation": 0.5,
                }
            )
    return pd.DataFrame(rows)


def test_summary_paired_and_best_by_hand():
    df = hand_table()
    s = summarise(df, ["x"])
    assert len(s) == 4 and list(s["n"]) == [3, 3, 3, 3]
    a0 = s[(s["point"] == 0) & (s["policy"] == "A")].iloc[0]
    half = 4.302653 * 2.0 / math.sqrt(3)  # sd of 80, 82, 84 is 2
    assert a0["gripping_rate_mean"] == 82.0
    assert a0["gripping_rate_ci_low"] == pytest.approx(82.0 - half, abs=1e-5)
    assert a0["gripping_rate_ci_high"] == pytest.approx(82.0 + half, abs=1e-5)
    assert a0["throughput_mean"] == pytest.approx(8.2)
    best = best_policies(s, ["x"])
    assert list(best["policy"]) == ["B", "A"]
    assert list(best["gripping_rate_mean"]) == [84.0, 90.0]
    paired = paired_differences(df, best, ["x"])
    row = paired[(paired["point"] == 0) & (paired["policy"] == "A")].iloc[0]
    half = 4.302653 * 1.0 / math.sqrt(3)  # diffs A - B = -1, -2, -3
    assert row["reference"] == "B" and row["diff_mean"] == -2.0
    assert row["diff_ci_low"] == pytest.approx(-2.0 - half, abs=1e-5)
    assert row["diff_ci_high"] == pytest.approx(-2.0 + half, abs=1e-5)
    same = paired[(paired["point"] == 0) & (paired["policy"] == "B")].iloc[0]
    assert (same["diff_mean"], same["diff_ci_low"], same["diff_ci_high"]) == (0.0, 0.0, 0.0)


def test_sizing_answer_is_the_smallest_count_with_lower_bound_over_target():
    line = load_scenario("paper_baseline")
    rows = []
    g = {1: [50, 52], 2: [90, 99], 3: [98.9, 99.5], 4: [99.5, 99.5], 5: [99.9, 100.0]}
    for point, (n, values) in enumerate(g.items()):
        for k, v in enumerate(values):
            rows.append(
                {
                    "point": point,
                    COUNT: n,
                    MTBF: 0.0,
                    "policy": "SD",
                    "replication": k,
                    "gripping_rate": v,
                    "throughput": 1.0 * n,
                    "efficiency": 1.0,
                    "utilisation": 1.0,
                    "part_flow": 10.0,
                }
            )
    df = pd.DataFrame(rows)
    s = analyse(df, summarise(df, [COUNT, MTBF]), [COUNT, MTBF], line, 99.0, 0.95)
    reached = {r[COUNT]: r["reached"] for r in s["rows"]}
    # n=2 mean 94.5 and n=3 mean 99.2 have wide intervals: not reached with confidence
    assert reached == {1: False, 2: False, 3: False, 4: True, 5: True}
    assert s["answer"] == 4
    assert s["rule_of_thumb"]["ppas"] == pytest.approx(1.0)  # throughput / (n x util) at n=1
    assert s["rule_of_thumb"]["n_min"] == pytest.approx(10.0)
    assert s["rule_of_thumb"]["n_recommended"] == 12
    assert s["breakdown"]["n_minus_1"]["robots"] == 3
    assert s["text"].startswith("4 robots running SD reach a 99 % gripping rate")


def test_sizing_setup_adds_counts_failures_and_belt():
    line = load_scenario("paper_baseline")
    sc, grid = sizing_setup(line, {COUNT: [2, 12]})  # 12 workspaces need more belt
    assert grid == {COUNT: [2, 12], MTBF: [0.0, 600.0]}
    need = 0.3 + 12 * line.robots.workspace_length
    assert sc.robots.mttr == 30.0 and sc.belt.length >= need > line.belt.length


def test_tiny_sizing_study(tmp_path):
    line = with_overrides(
        load_scenario("paper_baseline"),
        {
            "feeder.rate": 3.0,
            "duration": 40,
            "warmup": 5,
            "belt.length": 2.4,
            "sweep": {"grid": {COUNT: [1, 2, 3, 4]}, "policies": ["SPT"], "replications": 2},
        },
    )
    _, s = run_size(line, tmp_path, 80.0, Options(workers=1))
    plain = [r for r in s["rows"] if r[MTBF] == 0]
    means = [r["gripping_rate_mean"] for r in sorted(plain, key=lambda r: r[COUNT])]
    assert all(b >= a - 1.0 for a, b in zip(means, means[1:], strict=False))  # ~monotone
    reached = [r[COUNT] for r in plain if r["ci_low"] >= 80.0]
    assert s["answer"] == (min(reached) if reached else None)
    assert s["answer"] is not None and s["answer"] > 1
    saved = json.loads((tmp_path / "sizing.json").read_text())
    assert saved["answer"] == s["answer"] and saved["parameter"] == COUNT
    assert {"part_flow", "ppas", "n_min", "margin", "n_recommended"} <= set(saved["rule_of_thumb"])
    assert 0 < saved["breakdown"]["availability"] < 1
    assert np.isclose(saved["rule_of_thumb"]["part_flow"], 3.0, rtol=0.3)
    meta = json.loads((tmp_path / "meta.json").read_text())
    assert meta["kind"] == "size" and meta["grid"][MTBF] == [0.0, 600.0]
    # the run shown up close is the answer's line, not grid point 0 (2 robots)
    run = json.loads((tmp_path / "records" / "run.json").read_text())
    assert run["scenario"]["robots"]["count"] == s["answer"]
    assert run["scenario"]["robots"]["mtbf"] == 0


def test_sizing_layout_is_a_stated_choice(tmp_path):
    # a 3-robot line on a 2.0 m belt (issue 10, item 2): extend lengthens the belt and says
    # so; share keeps the 2.0 m belt and narrows the workspaces
    line = with_overrides(
        load_scenario("paper_baseline"),
        {
            "robots.count": 3,
            "robots.workspace_length": 0.5,  # the layout arithmetic below
            "belt.length": 2.0,
            "feeder.rate": 3.0,
            "duration": 30,
            "warmup": 5,
            "sweep": {"grid": {COUNT: [2, 3, 6]}, "policies": ["SPT"], "replications": 2},
        },
    )
    _, ext = run_size(line, tmp_path / "extend", 90.0, Options(workers=1))
    assert ext["layout"]["mode"] == "extend"
    assert ext["layout"]["counts"]["6"]["belt_length"] == pytest.approx(3.4)
    assert ext["layout"]["counts"]["6"]["workspace_length"] == pytest.approx(0.5)
    assert "lengthened from 2 m to 3.4 m" in ext["text"]
    _, sh = run_size(line, tmp_path / "share", 90.0, Options(workers=1), layout="share")
    counts = sh["layout"]["counts"]
    assert {c["belt_length"] for c in counts.values()} == {2.0}
    assert counts["6"]["workspace_length"] == pytest.approx(1.5 / 6)
    assert counts["3"]["workspaces"] == [[0.3, 0.8], [0.8, 1.3], [1.3, 1.8]]
    assert counts["6"]["workspaces"][-1][1] == pytest.approx(1.8)
    assert sh["text"].startswith("Layout: share.")
    meta = json.loads((tmp_path / "share" / "meta.json").read_text())
    assert meta["layout"] == "share"


def test_unknown_layout_is_a_one_line_error():
    from pnp_twin.studies.plan import StudyError

    with pytest.raises(StudyError, match="--layout: 'wide' is not allowed; allowed extend, share"):
        sizing_setup(load_scenario("paper_baseline"), {COUNT: [2]}, "wide")


def test_a_sweep_shows_its_base_line_up_close_not_point_0():
    from pnp_twin.studies.summary import showcase_point

    best = pd.DataFrame(
        {
            "point": [0, 1, 2],
            "robots.arm_speed": [2.0, 3.0, 4.0],
            "policy": ["SD", "SPT", "SD"],
            "gripping_rate_mean": [60.0, 70.0, 80.0],
        }
    )
    grid = {"robots.arm_speed": [2.0, 3.0, 4.0]}
    assert showcase_point(best, grid, {"robots": {"arm_speed": 3.0}}) == (1, "SPT")
    assert showcase_point(best, grid, {"robots": {"arm_speed": 2.5}}) == (1, "SPT")  # middle
    assert showcase_point(best, {}, {}) == (0, "SD")
