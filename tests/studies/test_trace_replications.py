"""Issue 19, arrival variability: several recorded traces as the replications of a point
(replication k replays trace k), so an interval across traces exists; every trace checked
up front; a mismatch or a bad trace refused with one line naming it."""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from pnp_twin.cli import app
from pnp_twin.reports import layout, load_study, render_report
from pnp_twin.reports.answers import headline
from pnp_twin.studies import Options, build_plan, run_sweep
from pnp_twin.studies.plan import StudyError
from pnp_twin.twin.loader import load_scenario
from pnp_twin.twin.trace import for_replication, trace_files

ROOT = Path(__file__).resolve().parents[2]
BASELINE = ROOT / "scenarios" / "paper_baseline.toml"
LINE = {"robots.count": 2, "duration": 30.0, "warmup": 5.0, "seed": 3}


def write_traces(folder: Path, n: int = 3) -> Path:
    """``n`` made-up traces of different burstiness, about 8 parts/s over 45 s."""
    folder.mkdir(parents=True, exist_ok=True)
    for k in range(n):
        rng = np.random.default_rng(10 + k)
        times = np.cumsum(rng.gamma(0.5 + k, 0.125 / (0.5 + k), 360))
        ys = rng.uniform(0.1, 0.3, 360)
        rows = "\n".join(f"{t:.4f},{y:.3f}" for t, y in zip(times, ys, strict=True))
        (folder / f"shift{k}.csv").write_text("time,y\n" + rows + "\n")
    return folder


def options() -> Options:
    opts = Options(workers=1, command="pnp-twin test")
    opts.engine = "simpy"
    return opts


@pytest.fixture(scope="module")
def traced(tmp_path_factory: pytest.TempPathFactory) -> Path:
    root = tmp_path_factory.mktemp("traces")
    folder = write_traces(root / "traces")
    over = {**LINE, "feeder.arrival": "trace", "feeder.trace": str(folder)}
    sc = load_scenario(BASELINE, overrides=over)
    out = root / "study"
    run_sweep(build_plan(sc, policies=["SD", "FIFO"], replications=3), out, options())
    return out


def test_three_traces_are_three_replications_with_a_real_interval(traced: Path) -> None:
    study = load_study(traced)
    results = study.results
    assert results is not None
    sd = results[results["policy"] == "SD"].sort_values("replication")
    assert sd["gripping_rate"].nunique() == 3  # each replication replays its own trace
    assert sd["part_flow"].nunique() == 3
    row = study.summary[study.summary["policy"] == "SD"].iloc[0]
    assert row["gripping_rate_ci_high"] - row["gripping_rate_ci_low"] > 0.1
    meta = json.loads((traced / "meta.json").read_text())
    assert meta["trace"]["traces"] == 3
    assert meta["trace"]["files"] == ["shift0.csv", "shift1.csv", "shift2.csv"]
    said = "mean of the 3 replayed traces (shift0.csv, shift1.csv, shift2.csv)"
    assert said in layout.facts(study)
    text = headline(study)
    assert "one replayed trace" not in text and "95 % CI" in text
    assert "one replayed trace" not in render_report(traced)


def test_a_list_of_traces_is_replayed_in_its_order(tmp_path: Path) -> None:
    folder = write_traces(tmp_path / "t")
    files = [str(folder / "shift2.csv"), str(folder / "shift0.csv")]
    sc = load_scenario(BASELINE, {**LINE, "feeder.arrival": "trace", "feeder.trace": files})
    assert [p.name for p in trace_files(sc)] == ["shift2.csv", "shift0.csv"]
    assert for_replication(sc, 1).feeder.trace == files[1]
    with pytest.raises(StudyError, match="--replications: 3, but feeder.trace names 2 traces"):
        build_plan(sc, policies=["SD"], replications=3)


def run_cli(tmp_path: Path, *args: str) -> tuple[int, str, str]:
    result = CliRunner().invoke(app, list(args), catch_exceptions=False)
    return result.exit_code, result.stdout, result.stderr


def study_args(trace: str, out: Path, reps: int = 3) -> list[str]:
    sets = {**LINE, "feeder.arrival": "trace", "feeder.trace": trace}
    return [
        "sweep",
        str(BASELINE),
        "--out",
        str(out),
        "-r",
        str(reps),
        "-p",
        "SD",
        *[x for k, v in sets.items() for x in ("--set", f"{k}={v}")],
    ]


@pytest.mark.parametrize("case", ["folder without csv", "one bad trace", "too many reps"])
def test_bad_traces_are_one_line_naming_the_file(tmp_path: Path, case: str) -> None:
    folder = write_traces(tmp_path / "traces")
    reps = 3
    if case == "folder without csv":
        folder = tmp_path / "empty"
        folder.mkdir()
        (folder / "notes.txt").write_text("no traces here\n")
        needles = ["feeder.trace", "empty", "folder without .csv traces"]
    elif case == "one bad trace":
        (folder / "shift1.csv").write_text("time,y\n0.1,0.2\n0.5,oops\n")
        needles = ["feeder.trace", "shift1.csv", "line 3", "non-numeric"]
    else:
        reps = 4
        needles = ["--replications: 4", "3 traces", "replication k replays trace k"]
    out = tmp_path / "out"
    before = sorted(os.listdir(tmp_path))
    code, stdout, stderr = run_cli(tmp_path, *study_args(str(folder), out, reps))
    assert code == 2 and stdout == ""
    lines = stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), stderr
    for needle in needles:
        assert needle in lines[0], (needle, lines[0])
    assert not out.exists() and sorted(os.listdir(tmp_path)) == before


def test_a_trace_past_its_end_is_refused_for_every_trace(tmp_path: Path) -> None:
    folder = write_traces(tmp_path / "traces")
    (folder / "shift3.csv").write_text("time,y\n0.1,0.2\n0.5,0.1\n")  # ends long before 30 s
    code, _, stderr = run_cli(tmp_path, *study_args(str(folder), tmp_path / "out", 3))
    assert code == 2 and "shift3.csv" in stderr and "duration" in stderr


def test_a_run_over_several_traces_replays_the_first_and_says_so(tmp_path: Path) -> None:
    folder = write_traces(tmp_path / "traces")
    sets = {**LINE, "feeder.arrival": "trace", "feeder.trace": str(folder)}
    args = ["run", str(BASELINE), "--json"]
    args += [x for k, v in sets.items() for x in ("--set", f"{k}={v}")]
    code, stdout, stderr = run_cli(tmp_path, *args)
    assert code == 0, stderr
    assert "3 traces; this run replays the first, 'shift0.csv'" in stderr
    assert json.loads(stdout)["gripping_rate"] > 0
