"""The ``pnp-twin`` command line: run, validate, schema, list, and the output writers."""

from __future__ import annotations

import json
import subprocess
import sys
import time
import tomllib
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from typer.testing import CliRunner

from pnp_twin.cli import app
from pnp_twin.twin.loader import load_scenario, shipped_scenarios
from pnp_twin.twin.output import (
    OutputError,
    dumps_json,
    dumps_toml,
    remove_temporaries,
    versions,
    write_json,
    write_table,
    write_text,
)
from pnp_twin.twin.scenario import Scenario

SHORT = ["--set", "duration=40", "--set", "warmup=5"]
ROOT = Path(__file__).resolve().parents[2]


def cli(*args: str) -> tuple[int, str, str]:
    """Run ``pnp-twin ARGS`` in-process: (exit code, stdout, stderr)."""
    result = CliRunner().invoke(app, list(args))
    return result.exit_code, result.stdout, result.stderr


def run_json(*args: str) -> dict:
    code, out, err = cli("run", *args, "--json")
    assert code == 0, err
    return json.loads(out)


def test_bare_command_shows_help() -> None:
    code, out, _ = cli()
    assert code == 0
    for command in ("run", "validate", "schema", "list"):
        assert command in out


def test_run_table_shows_the_kpis_of_the_json() -> None:
    kpis = run_json("two_robot", *SHORT)
    code, out, _ = cli("run", "two_robot", *SHORT)
    assert code == 0
    assert f"{kpis['gripping_rate']:.2f} %" in out
    assert f"{kpis['parts_presented']} / {kpis['parts_picked']} / {kpis['parts_missed']}" in out
    assert "Efficiency (of " in out and "Robots (upstream first" in out
    assert out.count("\n") > 10


def test_json_is_one_object_that_agrees_with_the_events_file(tmp_path: Path) -> None:
    events, spans = tmp_path / "out" / "parts.csv", tmp_path / "spans.parquet"
    code, out, err = cli(
        "run", "paper_baseline", *SHORT, "--json", "--events", str(events), "--spans", str(spans)
    )
    assert code == 0
    kpis = json.loads(out)  # the whole of stdout is one JSON object
    assert "wrote" in err and "{" not in err
    parts = pd.read_csv(events)
    window = parts[(parts["fed_at"] >= 5) & (parts["fed_at"] < 40)]
    picked = window[window["outcome"] == "picked"]
    assert kpis["parts_presented"] == len(window) > 0
    assert kpis["parts_picked"] == len(picked)
    assert kpis["parts_missed"] == int((window["outcome"] == "missed").sum())
    assert kpis["parts_presented"] == kpis["parts_picked"] + kpis["parts_missed"]
    per_robot = np.bincount(picked["robot"].astype(int) - 1, minlength=4)  # robots from 1
    assert [r["picks"] for r in kpis["robots"]] == per_robot.tolist()
    assert kpis["gripping_rate"] == pytest.approx(100 * len(picked) / len(window))
    states = pd.read_parquet(spans)
    assert list(states.columns) == ["robot", "state", "start", "end"]
    noops = states[(states["state"] == "noop") & (states["start"] >= 5) & (states["start"] < 40)]
    assert kpis["decisions"]["NooP"] == len(noops)


def test_events_parquet_holds_the_same_records_as_csv(tmp_path: Path) -> None:
    for name in ("e.csv", "e.parquet"):
        assert cli("run", "two_robot", *SHORT, "--events", str(tmp_path / name))[0] == 0
    csv, parquet = pd.read_csv(tmp_path / "e.csv"), pd.read_parquet(tmp_path / "e.parquet")
    assert len(csv) == len(parquet) > 0
    assert (csv["outcome"] == parquet["outcome"]).all()
    assert np.allclose(csv["fed_at"], parquet["fed_at"])


def test_json_writes_nan_as_null() -> None:
    # a trickle of parts: the downstream robot picks nothing, so its mean cycle time is NaN
    code, out, _ = cli(
        "run", "two_robot", "--json", "--set", "feeder.rate=0.05", "--set", "duration=60",
        "--set", "warmup=1", "--policy", "FIFO",
    )  # fmt: skip
    assert code == 0
    assert "NaN" not in out and "Infinity" not in out
    kpis = json.loads(out, parse_constant=lambda c: pytest.fail(f"invalid JSON constant {c}"))
    assert kpis["robots"][1]["picks"] == 0
    assert kpis["robots"][1]["cycle_time_mean"] is None


def test_same_seed_same_result_other_seed_differs() -> None:
    a = run_json("paper_baseline", *SHORT, "--seed", "11")
    b = run_json("paper_baseline", *SHORT, "--seed", "11")
    c = run_json("paper_baseline", *SHORT, "--seed", "12")
    assert a == b
    assert a["seed"] == 11 and c["seed"] == 12
    assert (a["parts_presented"], a["parts_picked"]) != (c["parts_presented"], c["parts_picked"])


def test_policy_mix_and_overrides_reach_the_run() -> None:
    kpis = run_json("paper_baseline", *SHORT, "--policy", "spt,spt,fifo", "--set", "robots.count=3")
    assert kpis["policy"] == "SPT,SPT,FIFO"
    assert len(kpis["robots"]) == 3
    assert {"SPT", "FIFO"} <= set(kpis["decisions"])
    assert kpis["decisions"]["SPT"] + kpis["decisions"]["FIFO"] == kpis["parts_picked"]


def test_default_policy_is_the_scenarios() -> None:
    assert run_json("two_robot", *SHORT)["policy"] == load_scenario("two_robot").policy


@pytest.mark.parametrize("fmt, suffix", [("toml", ".toml"), ("yaml", ".yaml")])
def test_validate_prints_a_scenario_that_loads_back(tmp_path: Path, fmt: str, suffix: str) -> None:
    code, out, err = cli("validate", "trace_replay", "--set", "feeder.trace=traces/sample_line.csv",
                         "--set", "robots.arm_speed=3.5", "--format", fmt)  # fmt: skip
    assert code == 0 and err.startswith("ok: ")
    copy = tmp_path / f"copy{suffix}"
    copy.write_text(out)
    again = load_scenario(copy)  # from another folder: the trace path was made absolute
    original = load_scenario("trace_replay", {"robots.arm_speed": 3.5})
    assert again.robots.arm_speed == 3.5
    assert Path(again.feeder.trace or "").is_absolute()
    skip = {"source_dir": True, "feeder": {"trace"}}
    assert again.model_dump(exclude=skip) == original.model_dump(exclude=skip)


@pytest.mark.parametrize("name", shipped_scenarios())
def test_validate_round_trips_every_shipped_scenario(tmp_path: Path, name: str) -> None:
    code, out, _ = cli("validate", name)
    assert code == 0
    (tmp_path / "again.toml").write_text(out)
    again, original = load_scenario(tmp_path / "again.toml"), load_scenario(name)
    skip = {"source_dir": True, "feeder": {"trace"}}
    assert again.model_dump(exclude=skip) == original.model_dump(exclude=skip)


def test_validate_of_baseline_is_toml_with_every_section() -> None:
    code, out, _ = cli("validate", "paper_baseline")
    assert code == 0
    data = tomllib.loads(out)
    assert {"belt", "feeder", "robots", "bins"} <= set(data)
    assert data["robots"]["count"] == 4 and "source_dir" not in data


def test_schema_prints_the_scenario_schema(tmp_path: Path) -> None:
    code, out, _ = cli("schema")
    assert code == 0
    schema = json.loads(out)
    assert set(schema["properties"]) == set(Scenario.model_fields)
    assert schema["additionalProperties"] is False
    target = tmp_path / "sub" / "s.json"
    assert cli("schema", "--out", str(target))[0] == 0
    assert target.read_text() == out


def test_list_names_every_shipped_scenario() -> None:
    code, out, _ = cli("list")
    assert code == 0
    for name in ("paper_baseline", "two_robot", "trace_replay", "breakdowns"):
        assert name in out
    for model in ("paper_baseline__async_rollout", "paper_baseline__sync"):  # by name, too
        assert model in out.replace("\n", "")


def test_keyboard_interrupt_exits_130_with_one_line(monkeypatch: pytest.MonkeyPatch) -> None:
    def interrupted(*args: object, **kwargs: object) -> None:
        raise KeyboardInterrupt

    monkeypatch.setattr("pnp_twin.cli.run_cmd.simulate", interrupted)
    code, out, err = cli("run", "two_robot", *SHORT)
    assert code == 130
    assert err == "error: interrupted\n" and out == ""


def test_python_m_pnp_twin_runs_and_fails_cleanly(tmp_path: Path) -> None:
    ok = subprocess.run(
        [sys.executable, "-m", "pnp_twin", "run", "two_robot", *SHORT, "--json"],
        capture_output=True, text=True, cwd=tmp_path, timeout=120,
    )  # fmt: skip
    assert ok.returncode == 0, ok.stderr
    assert json.loads(ok.stdout)["scenario"] == "two_robot"
    bad = subprocess.run(
        [sys.executable, "-m", "pnp_twin", "run", "missing.toml", "--json"],
        capture_output=True, text=True, cwd=tmp_path, timeout=120,
    )  # fmt: skip
    assert bad.returncode == 2
    assert bad.stdout == ""
    assert len(bad.stderr.splitlines()) == 1 and "Traceback" not in bad.stderr
    assert bad.stderr.startswith("error: ") and "missing.toml" in bad.stderr


# --- twin.output: the atomic writers ---------------------------------------------------------


def test_writers_replace_atomically_and_leave_no_temp_files(tmp_path: Path) -> None:
    target = tmp_path / "deep" / "k.json"
    write_json({"g": float("nan"), "n": np.int64(3), "xs": np.array([1.5, np.inf])}, target)
    assert json.loads(target.read_text()) == {"g": None, "n": 3, "xs": [1.5, None]}
    write_text("second\n", target)
    assert target.read_text() == "second\n"
    df = pd.DataFrame({"a": [1, 2], "b": ["x", None]})
    write_table(df, tmp_path / "t.parquet")
    assert pd.read_parquet(tmp_path / "t.parquet").equals(df)
    assert sorted(p.name for p in tmp_path.rglob("*")) == ["deep", "k.json", "t.parquet"]


def test_write_table_rejects_other_suffixes(tmp_path: Path) -> None:
    with pytest.raises(OutputError, match=r"'.*t\.xlsx' has suffix '.xlsx'; allowed .csv"):
        write_table(pd.DataFrame({"a": [1]}), tmp_path / "t.xlsx")
    assert not list(tmp_path.iterdir())


def test_dumps_toml_round_trips_nested_tables() -> None:
    data = {
        "name": 'a "quoted" name',
        "x": 0.1,
        "flag": True,
        "grid": [64, 8],
        "skip": None,
        "belt": {"speed": 0.8, "pair": [[0.3, 0.8], [0.8, 1.3]]},
        "robots": {"count": 2, "overrides": [{"robot": 1, "arm_speed": 4.0}, {"robot": 2}]},
        "sweep": {"grid": {"robots.count": [2, 3]}},
    }
    back = tomllib.loads(dumps_toml(data))
    expected = {k: v for k, v in data.items() if k != "skip"}
    assert back == expected
    assert dumps_json({"v": [float("-inf")]}) == '{"v": [null]}'


def test_write_json_keeps_nan_when_asked_so_rows_round_trip(tmp_path: Path) -> None:
    target = tmp_path / "row.json"
    write_json({"g": float("nan"), "p": tmp_path, "n": np.float64(2.5)}, target, keep_nan=True)
    back = json.loads(target.read_text())
    assert np.isnan(back["g"]) and back["p"] == str(tmp_path) and back["n"] == 2.5


def test_versions_name_python_and_each_distribution() -> None:
    v = versions("pnp-twin", "numpy", "no-such-dist-xyz")
    assert list(v) == ["python", "pnp_twin", "numpy", "no_such_dist_xyz"]
    assert v["numpy"] == np.__version__ and v["no_such_dist_xyz"] == "unknown"


def test_remove_temporaries_removes_only_the_writers_names(tmp_path: Path) -> None:
    ours = tmp_path / ".results.parquet.0123456789ab.tmp"
    other = tmp_path / ".notes.tmp"
    for p in (ours, other):
        p.write_text("x")
    assert remove_temporaries(tmp_path) == [ours]
    assert not ours.exists() and other.exists()


@pytest.mark.parametrize("spans", ["same.csv", "./sub/../same.csv"])
def test_events_and_spans_into_one_file_is_refused(tmp_path: Path, spans: str) -> None:
    events = tmp_path / "same.csv"
    events.write_text("keep me\n")
    code, _, err = cli("run", "paper_baseline", *SHORT, "--events", str(events),
                       "--spans", str(tmp_path / spans))  # fmt: skip
    assert code == 2
    assert err.strip().startswith("error: --spans: '") and "is the file --events writes" in err
    assert len(err.strip().splitlines()) == 1 and events.read_text() == "keep me\n"


def test_sweep_on_an_unreachable_ray_address_fails_fast(tmp_path: Path) -> None:
    pytest.importorskip("ray")
    t0 = time.monotonic()
    code, _, err = cli("sweep", "paper_baseline", "--out", str(tmp_path / "s"), "--no-report",
                       "--backend", "ray", "--address", "127.0.0.1:1", "-r", "2",
                       "--set", "sweep.grid={'feeder.rate': [8.0]}", "--set", "sweep.duration=20",
                       "--set", "sweep.warmup=2",
                       "--policy", "SD")  # fmt: skip
    assert code == 2 and time.monotonic() - t0 < 30
    assert err.strip().splitlines() == [
        "error: --address 127.0.0.1:1: cannot connect to Ray (Connection refused within 10 s); "
        "check the address and that the cluster is running"
    ]
