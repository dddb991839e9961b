"""The vectorised summaries give the very doubles (and CSV bytes) of a t-interval per
group: checked against the per-group loops they replaced, on a real sweep's rows and on
awkward tables (NaN, unequal and single replications, a missing reference run)."""

from __future__ import annotations

import io

import numpy as np
import pandas as pd
import pytest

from pnp_twin.studies.summary import (
    BOUNDS,
    KPIS,
    best_policies,
    grouped_intervals,
    paired_differences,
    summarise,
)
from pnp_twin.twin.stats import t_interval


def loop_summarise(results, grid, confidence=0.95):
    rows = []
    for (point, policy), g in results.groupby(["point", "policy"], sort=True):
        row = {"point": point, **{c: g[c].iloc[0] for c in grid}, "policy": policy, "n": len(g)}
        for kpi in KPIS:
            mean, low, high = t_interval(g[kpi].to_numpy(), confidence)
            if kpi in BOUNDS:
                low, high = max(low, BOUNDS[kpi][0]), min(high, BOUNDS[kpi][1])
            row.update({f"{kpi}_mean": mean, f"{kpi}_ci_low": low, f"{kpi}_ci_high": high})
        rows.append(row)
    return pd.DataFrame(rows)


def loop_paired(results, best, grid, confidence=0.95):
    rows = []
    reference = dict(zip(best["point"], best["policy"], strict=True))
    for (point, policy), g in results.groupby(["point", "policy"], sort=True):
        ref = reference[point]
        at = results[(results["point"] == point) & (results["policy"] == ref)]
        mine = g.set_index("replication")["gripping_rate"]
        theirs = at.set_index("replication")["gripping_rate"]
        diff = (mine - theirs).dropna()
        mean, low, high = t_interval(diff.to_numpy(), confidence)
        rows.append(
            {
                "point": point,
                **{c: g[c].iloc[0] for c in grid},
                "policy": policy,
                "reference": ref,
                "diff_mean": mean,
                "diff_ci_low": low,
                "diff_ci_high": high,
                "n": len(diff),
            }
        )
    return pd.DataFrame(rows)


def csv(df: pd.DataFrame) -> str:
    buf = io.StringIO()
    df.to_csv(buf, index=False)
    return buf.getvalue()


def same(new: pd.DataFrame, old: pd.DataFrame) -> None:
    pd.testing.assert_frame_equal(new, old, check_exact=True)
    assert csv(new) == csv(old)


def synthetic(seed: int, reps: int = 5) -> pd.DataFrame:
    rng = np.random.default_rng(seed)
    rows = []
    for point in range(6):
        for policy in ("SD", "FIFO", "SPT", "LD"):
            for k in range(reps):
                g = float(rng.normal(85.0, 6.0))
                rows.append(
                    {
                        "run_id": f"p{point:03d}-{policy}-r{k:02d}",
                        "point": point,
                        "feeder.rate": [8.0, 10.0, 12.0][point % 3],
                        "robots.count": 2 + point // 3,
                        "policy": policy,
                        "replication": k,
                        "gripping_rate": min(100.0, g),
                        "throughput": float(rng.normal(9.0, 0.5)),
                        "efficiency": float(rng.uniform(0.9, 1.0)),
                        "utilisation": float(rng.uniform(0.0, 0.2)),
                    }
                )
    df = pd.DataFrame(rows)
    return df.sort_values(["point", "policy", "replication"]).reset_index(drop=True)


GRID = ["feeder.rate", "robots.count"]


@pytest.mark.parametrize("seed", range(4))
@pytest.mark.parametrize("confidence", [0.9, 0.95, 0.97])
def test_the_summaries_are_the_loops_doubles(seed, confidence):
    results = synthetic(seed)
    summary = summarise(results, GRID, confidence)
    same(summary, loop_summarise(results, GRID, confidence))
    best = best_policies(summary, GRID)
    same(
        paired_differences(results, best, GRID, confidence),
        loop_paired(results, best, GRID, confidence),
    )


def test_awkward_tables_too():
    results = synthetic(7, reps=12)
    results.loc[3, "throughput"] = np.nan  # an undefined KPI in one run
    results.loc[results["policy"] == "SPT", "efficiency"] = np.nan  # undefined for a policy
    results.loc[17, "gripping_rate"] = np.nan
    results = results.drop(index=[40, 41, 77])  # unequal replications, a reference run missing
    lone = (results["point"] == 5) & (results["policy"] == "LD") & (results["replication"] > 0)
    results = results[~lone].reset_index(drop=True)  # one replication only
    results.loc[results["gripping_rate"] > 99.0, "gripping_rate"] = 100.0  # ties at the bound
    summary = summarise(results, GRID)
    same(summary, loop_summarise(results, GRID))
    best = best_policies(summary, GRID)
    same(paired_differences(results, best, GRID), loop_paired(results, best, GRID))
    shuffled = results.sample(frac=1.0, random_state=1)  # groupby's order, whatever the input's
    same(summarise(shuffled, GRID), loop_summarise(shuffled, GRID))


def test_a_real_sweeps_rows():
    from pnp_twin.studies import build_plan
    from pnp_twin.studies.execute import execute
    from pnp_twin.studies.folder import results_frame
    from pnp_twin.twin import load_scenario, with_overrides

    line = with_overrides(load_scenario("paper_baseline"), {"duration": 30, "warmup": 5})
    grid = {"feeder.rate": [8.0, 12.0], "robots.arm_speed": [2.0, 4.0]}
    plan = build_plan(line, grid=grid, policies=["SD", "FIFO", "SPT"], replications=3)
    results = results_frame([execute(s) for s in plan.specs()], list(plan.grid))
    summary = summarise(results, list(plan.grid))
    same(summary, loop_summarise(results, list(plan.grid)))
    best = best_policies(summary, list(plan.grid))
    same(
        paired_differences(results, best, list(plan.grid)),
        loop_paired(results, best, list(plan.grid)),
    )


def test_grouped_intervals_match_t_interval_row_by_row():
    rng = np.random.default_rng(0)
    counts = rng.integers(0, 40, 300)
    values = rng.normal(50.0, 20.0, counts.sum()) * 10.0 ** rng.integers(-3, 4, counts.sum())
    values[rng.random(len(values)) < 0.01] = np.nan
    starts = np.concatenate(([0], np.cumsum(counts)[:-1]))
    mean, low, high = grouped_intervals(values, starts, counts, 0.95)
    for g, (s, n) in enumerate(zip(starts, counts, strict=True)):
        want = t_interval(values[s : s + n], 0.95)
        got = (mean[g], low[g], high[g])
        assert np.array_equal(np.array(got), np.array(want), equal_nan=True), g
