"""Running studies: workers, resume, the Ray backend, the folder contract, the CLI."""

from __future__ import annotations

import json
import signal
import sqlite3
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from typer.testing import CliRunner

from pnp_twin.studies import Options, build_plan, run_sweep
from pnp_twin.studies.journal import journaled
from pnp_twin.studies.plan import StudyError
from pnp_twin.twin import load_scenario, with_overrides

GRID = {"robots.arm_speed": [2.0, 4.0], "feeder.rate": [8.0, 12.0]}


@pytest.fixture(scope="module")
def plan():
    line = with_overrides(load_scenario("paper_baseline"), {"duration": 40, "warmup": 5})
    return build_plan(line, grid=GRID, policies=["SD", "FIFO"], replications=2)


def table(folder: Path) -> pd.DataFrame:
    return pd.read_parquet(folder / "results.parquet").drop(columns="wall_time")


@pytest.fixture(scope="module")
def serial(plan, tmp_path_factory):
    out = tmp_path_factory.mktemp("serial")
    run_sweep(plan, out, Options(workers=1))
    return out


def test_folder_contract(serial, plan):
    df = pd.read_parquet(serial / "results.parquet")
    assert len(df) == 4 * 2 * 2
    assert list(df.columns[:7]) == [
        "run_id",
        "point",
        "robots.arm_speed",
        "feeder.rate",
        "policy",
        "replication",
        "seed",
    ]
    assert df.columns[-1] == "wall_time"
    for c in ("gripping_rate", "throughput", "efficiency", "r4_utilisation", "rule_SD"):
        assert c in df.columns
    assert df.equals(df.sort_values(["point", "policy", "replication"]).reset_index(drop=True))
    # common random numbers: one seed per replication, and so one part stream per rate
    assert df.groupby("replication")["seed"].nunique().eq(1).all()
    same = df[(df["feeder.rate"] == 8.0) & (df["replication"] == 0)]
    assert same["parts_presented"].nunique() == 1
    csv = pd.read_csv(serial / "results.csv")
    assert list(csv.columns) == list(df.columns) and len(csv) == len(df)
    summary = pd.read_csv(serial / "summary.csv")
    assert len(summary) == 8 and summary["n"].eq(2).all()
    assert {"gripping_rate_ci_low", "utilisation_mean"} <= set(summary.columns)
    best = pd.read_csv(serial / "best.csv")
    paired = pd.read_csv(serial / "paired.csv")
    assert len(best) == 4 and len(paired) == 8
    assert (paired["reference"] == paired["point"].map(best.set_index("point")["policy"])).all()
    meta = json.loads((serial / "meta.json").read_text())
    assert meta["kind"] == "sweep" and meta["replications"] == 2
    assert meta["grid"] == {k: list(v) for k, v in GRID.items()}
    assert {"pnp_twin", "python", "simpy", "numpy", "pandas", "plotly"} <= set(meta["versions"])
    run = json.loads((serial / "records" / "run.json").read_text())
    assert run["point"] == 0 and run["replication"] == 0 and run["policy"] == best["policy"][0]
    parts = pd.read_parquet(serial / "records" / "parts.parquet")
    row = df[(df["point"] == 0) & (df["replication"] == 0) & (df["policy"] == run["policy"])]
    assert (parts["outcome"] == "picked").sum() >= int(row["parts_picked"].iloc[0])
    assert len(journaled(serial / "runs")) == 16


def test_best_is_the_argmax_of_the_summary(serial):
    # best.csv, per point: the policy with the highest mean gripping rate, computed here from
    # the raw results and checked against summary.csv
    results = pd.read_parquet(serial / "results.parquet")
    means = results.groupby(["point", "policy"])["gripping_rate"].mean()
    summary = pd.read_csv(serial / "summary.csv").set_index(["point", "policy"])
    assert np.allclose(summary.loc[means.index, "gripping_rate_mean"], means, rtol=0, atol=1e-9)
    best = pd.read_csv(serial / "best.csv").set_index("point")
    assert sorted(best.index) == sorted(results["point"].unique())
    for point, row in best.iterrows():
        at = means.loc[point]
        assert row["gripping_rate_mean"] == pytest.approx(at.max(), abs=1e-9), point
        assert at[row["policy"]] == at.max(), (point, row["policy"], at.to_dict())
    # the grid columns agree with the summary's for each point
    for col in GRID:
        got = best[col].sort_index()
        want = summary.reset_index().groupby("point")[col].first().sort_index()
        assert got.tolist() == want.tolist(), col
    assert means.groupby("point").nunique().min() > 1  # the policies differ: a real choice


def test_two_workers_give_the_same_table(serial, plan, tmp_path):
    run_sweep(plan, tmp_path, Options(workers=2))
    pd.testing.assert_frame_equal(table(tmp_path), table(serial))
    pd.testing.assert_frame_equal(
        pd.read_csv(tmp_path / "summary.csv"), pd.read_csv(serial / "summary.csv")
    )


def test_resume_skips_finished_runs(serial, plan, tmp_path):
    run_sweep(plan, tmp_path, Options(workers=1))
    db = sqlite3.connect(tmp_path / "runs" / "runs.sqlite")
    with db:
        db.execute("DELETE FROM runs WHERE rowid BETWEEN 4 AND 9")  # six runs lost
    db.close()
    (tmp_path / "results.parquet").unlink()
    (tmp_path / "runs" / ".runs.sqlite.0123456789ab.tmp").write_text("{")  # killed copy
    (tmp_path / ".results.parquet.a1b2c3d4e5f6.tmp").write_text("PAR1")  # killed final write
    seen: list[tuple[int, int]] = []
    run_sweep(plan, tmp_path, Options(workers=1, progress=lambda d, t: seen.append((d, t))))
    assert seen[1] == (10, 16) and seen[-1] == (16, 16)  # 10 skipped, 6 run
    meta = json.loads((tmp_path / "meta.json").read_text())
    assert meta["runs_skipped"] == 10 and meta["runs_executed"] == 6
    df = table(tmp_path)
    assert df["run_id"].is_unique
    pd.testing.assert_frame_equal(df, table(serial))
    assert not list((tmp_path / "runs").glob(".*.tmp")) and not list(tmp_path.glob(".*.tmp"))


def test_changed_definition_needs_fresh(plan, serial, tmp_path):
    run_sweep(plan, tmp_path, Options(workers=1))
    other = build_plan(plan.scenario, grid=GRID, policies=["SD"], replications=2)
    with pytest.raises(
        StudyError,
        match=r"holds a different study \(policies was \[\"SD\", \"FIFO\"\], "
        r"now \[\"SD\"\]\).*--fresh",
    ):
        run_sweep(other, tmp_path, Options(workers=1))
    run_sweep(other, tmp_path, Options(workers=1, fresh=True))
    df = table(tmp_path)
    assert set(df["policy"]) == {"SD"}
    assert len(journaled(tmp_path / "runs")) == 8
    old = table(serial)
    old = old[old["policy"] == "SD"].reset_index(drop=True)
    assert set(old.columns) - set(df.columns) == {"rule_FIFO"}  # no FIFO decisions any more
    pd.testing.assert_frame_equal(df, old[df.columns])


def test_ray_backend_matches_local(tmp_path, foreign_signal_handlers):
    pytest.importorskip("ray")
    line = with_overrides(load_scenario("paper_baseline"), {"duration": 30, "warmup": 5})
    tiny = build_plan(line, grid={"feeder.rate": [8.0, 12.0]}, policies=["SD"], replications=2)
    run_sweep(tiny, tmp_path / "local", Options(workers=1))
    run_sweep(tiny, tmp_path / "ray", Options(backend="ray", workers=2))
    pd.testing.assert_frame_equal(table(tmp_path / "ray"), table(tmp_path / "local"))
    # ray.init installs a SIGTERM handler in the caller; the caller's own ones are given back
    for s, handler in foreign_signal_handlers.items():
        assert signal.getsignal(s) is handler, signal.Signals(s).name


def test_unknown_backend_is_an_error(plan, tmp_path):
    with pytest.raises(StudyError, match="--backend: 'dask' is not allowed; allowed local, ray"):
        run_sweep(plan, tmp_path, Options(backend="dask"))


def cli():
    import pnp_twin.cli.study_cmd  # noqa: F401  (registers sweep, size, mix)
    from pnp_twin.cli.app import app

    return app


def test_cli_sweep_and_resume(tmp_path):
    app = cli()
    args = [
        "sweep",
        "paper_baseline",
        "--out",
        str(tmp_path),
        "--workers",
        "1",
        "--no-report",
        "--set",
        "sweep.grid={'feeder.rate': [8.0, 12.0]}",
        "--set",
        "sweep.duration=30",
        "--set",
        "sweep.warmup=5",
        "--replications",
        "2",
        "--policy",
        "SD",
        "--policy",
        "SPT",
    ]
    first = CliRunner().invoke(app, args)
    assert first.exit_code == 0, first.output
    assert "Best policy per grid point" in first.stdout
    assert len(pd.read_parquet(tmp_path / "results.parquet")) == 8
    again = CliRunner().invoke(app, args)
    assert again.exit_code == 0
    assert json.loads((tmp_path / "meta.json").read_text())["runs_skipped"] == 8


def test_cli_bad_sweep_path_is_one_line_exit_2(tmp_path):
    result = CliRunner().invoke(
        cli(),
        [
            "sweep",
            "paper_baseline",
            "--out",
            str(tmp_path),
            "--set",
            "sweep.grid={'robots.arm_sped': [2, 4]}",
        ],
    )
    assert result.exit_code == 2
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and "'robots.arm_sped' is not a scenario field" in lines[0]
    assert not (tmp_path / "runs").exists()


def test_adding_replications_keeps_the_earlier_runs(plan, serial, tmp_path):
    one = build_plan(plan.scenario, grid=GRID, policies=["SD", "FIFO"], replications=1)
    run_sweep(one, tmp_path, Options(workers=1))
    run_sweep(plan, tmp_path, Options(workers=1))  # 1 -> 2 replications: no --fresh needed
    meta = json.loads((tmp_path / "meta.json").read_text())
    assert meta["runs_skipped"] == 8 and meta["runs_executed"] == 8
    pd.testing.assert_frame_equal(table(tmp_path), table(serial))


def test_a_failed_fresh_start_leaves_the_old_study_intact(plan, tmp_path):
    tiny = build_plan(plan.scenario, grid={"feeder.rate": [8.0]}, policies=["SD"], replications=2)
    run_sweep(tiny, tmp_path, Options(workers=1))
    before = {p.name: p.read_bytes() for p in tmp_path.iterdir() if p.is_file()}
    runs = sorted(p.name for p in (tmp_path / "runs").iterdir())
    with pytest.raises(StudyError, match="--backend"):
        run_sweep(tiny, tmp_path, Options(backend="dask", fresh=True))
    after = {p.name: p.read_bytes() for p in tmp_path.iterdir() if p.is_file()}
    assert after == before and sorted(p.name for p in (tmp_path / "runs").iterdir()) == runs
    assert not (tmp_path / ".replaced").exists()
    run_sweep(tiny, tmp_path, Options(workers=1, fresh=True))  # the lock was let go
    assert json.loads((tmp_path / "meta.json").read_text())["runs_executed"] == 2


def test_auto_replications_add_rounds_until_the_half_width_is_met(plan, tmp_path):
    grid = {"feeder.rate": [8.0, 12.0]}
    auto = build_plan(
        plan.scenario,
        grid=grid,
        policies=["SD"],
        replications="auto",
        half_width=0.01,
        max_replications=5,
    )
    assert auto.replications == 3 and auto.precision is not None
    run_sweep(auto, tmp_path / "auto", Options(workers=1))
    meta = json.loads((tmp_path / "auto" / "meta.json").read_text())
    p = meta["precision"]
    assert p["rounds"] == [3, 5] and p["replications"] == 5 == meta["replications"]
    assert p["reached"] is False and p["points_short"] == 2 and p["half_width_max"] > 0.01
    assert p["target_half_width"] == 0.01 and p["kpi"] == "gripping_rate"
    fixed = build_plan(plan.scenario, grid=grid, policies=["SD"], replications=5)
    run_sweep(fixed, tmp_path / "fixed", Options(workers=1))
    pd.testing.assert_frame_equal(table(tmp_path / "auto"), table(tmp_path / "fixed"))
    summary = pd.read_csv(tmp_path / "auto" / "summary.csv")
    half = (summary["gripping_rate_ci_high"] - summary["gripping_rate_ci_low"]) / 2
    assert half.max() == pytest.approx(p["half_width_max"])
    wide = build_plan(
        plan.scenario, grid=grid, policies=["SD"], replications="auto", half_width=50.0
    )
    run_sweep(wide, tmp_path / "wide", Options(workers=1))
    p = json.loads((tmp_path / "wide" / "meta.json").read_text())["precision"]
    assert p["rounds"] == [3] and p["reached"] is True and p["max_replications"] == 30


@pytest.mark.parametrize(
    ("kw", "needle"),
    [
        ({"replications": "auto"}, "--half-width: replications = auto needs"),
        ({"replications": "auto", "half_width": -1.0}, "--half-width: -1.0 is not allowed"),
        ({"replications": "auto", "half_width": 1.0, "max_replications": 1}, "--max-rep"),
        ({"replications": 3, "half_width": 1.0}, "--half-width: only with --replications auto"),
        ({"replications": 0}, "--replications: 0 is not allowed"),
    ],
)
def test_bad_replication_settings_are_one_line(plan, kw, needle):
    with pytest.raises(StudyError, match=needle):
        build_plan(plan.scenario, grid={}, policies=["SD"], **kw)


def test_cli_auto_replications_and_the_same_file_twice(tmp_path):
    app = cli()
    args = [
        "sweep",
        "paper_baseline",
        "--out",
        str(tmp_path),
        "-w",
        "1",
        "--no-report",
        "--set",
        "sweep.grid={'feeder.rate': [8.0]}",
        "--set",
        "sweep.duration=20",
        "--set",
        "sweep.warmup=2",
        "--policy",
        "SD",
        "--replications",
        "auto",
        "--half-width",
        "40",
        "--max-replications",
        "4",
    ]
    result = CliRunner().invoke(app, args)
    assert result.exit_code == 0, result.output
    assert "replications: 3 (rounds 3); target half-width 40 points met" in result.stderr
    bad = CliRunner().invoke(app, [*args[:-6], "--replications", "many"])
    assert bad.exit_code == 2
    assert bad.stderr.strip() == (
        "error: --replications: 'many' is not allowed; give a whole number >= 1 or auto"
    )
