"""Every kind of bad input ends with exit code 2 and one line naming the field and the value."""

from __future__ import annotations

from pathlib import Path

import pytest
from typer.testing import CliRunner

from pnp_twin.cli import app

# name -> (files to write in the working folder, command line, substrings the line must hold)
CASES: dict[str, tuple[dict[str, str], list[str], list[str]]] = {
    "missing file": ({}, ["run", "nothere.toml"], ["scenario", "nothere.toml", "shipped name"]),
    "unknown shipped name": ({}, ["validate", "papr_baseline"], ["papr_baseline"]),
    "wrong suffix": ({"s.json": "{}"}, ["run", "s.json"], ["'.json'", ".toml, .yaml"]),
    "bad TOML": ({"b.toml": "[belt\nspeed = 1\n"}, ["run", "b.toml"], ["b.toml", "valid TOML"]),
    "bad YAML": ({"b.yaml": "belt: [1, 2\n"}, ["run", "b.yaml"], ["b.yaml", "valid YAML"]),
    "YAML list": ({"l.yaml": "- 1\n- 2\n"}, ["run", "l.yaml"], ["l.yaml", "mapping"]),
    "unknown key": (
        {"u.toml": "[belt]\nspede = 1\n"},
        ["run", "u.toml"],
        ["belt.spede", "unknown"],
    ),
    "out of range": ({"r.toml": "[belt]\nspeed = -1\n"}, ["run", "r.toml"], ["belt.speed", "-1"]),
    "wrong type": (
        {"t.toml": '[robots]\ncount = "four"\n'},
        ["validate", "t.toml"],
        ["robots.count", "four", "integer"],
    ),
    "arm slower than belt": (
        {"a.yaml": "robots:\n  arm_speed: 0.5\n"},
        ["run", "a.yaml"],
        ["robots.arm_speed", "0.5", "belt.speed"],
    ),
    "unknown policy in file": (
        {"p.toml": 'policy = "FASTEST"\n'},
        ["run", "p.toml"],
        ["policy", "FASTEST", "SPT"],
    ),
    "unknown policy on the command line": (
        {},
        ["run", "two_robot", "--policy", "nearest"],
        ["policy", "NEAREST", "FIFO"],
    ),
    "policy mix of wrong length": (
        {},
        ["run", "paper_baseline", "--policy", "SD,SD,FIFO"],
        ["SD,SD,FIFO", "3 rules for 4 robots"],
    ),
    "policy mix of wrong length in validate": (
        {"m.toml": 'policy = "SD,LD"\n[robots]\ncount = 3\nworkspace_length = 0.5\n'},
        ["validate", "m.toml"],
        ["SD,LD", "2 rules for 3 robots"],
    ),
    "--set without =": (
        {},
        ["run", "two_robot", "--set", "robots.count"],
        ["--set", "robots.count"],
    ),
    "--set unknown key": (
        {},
        ["run", "two_robot", "--set", "belt.spede=1"],
        ["belt.spede", "unknown"],
    ),
    "--set into a value": (
        {},
        ["run", "two_robot", "--set", "belt.speed.max=1"],
        ["belt.speed", "not a section"],
    ),
    "--set wrong type": ({}, ["run", "two_robot", "--set", "duration=soon"], ["duration", "soon"]),
    "--set warm-up past the end": (
        {},
        ["run", "two_robot", "--set", "warmup=900"],
        ["warmup", "900", "duration"],
    ),
    "bad events suffix": (
        {},
        ["run", "two_robot", "--events", "parts.xlsx"],
        ["--events", "parts.xlsx", ".csv, .parquet"],
    ),
    "bad spans suffix": ({}, ["run", "two_robot", "--spans", "spans"], ["--spans", ".csv"]),
    "events path is a folder": (
        {"out.csv/keep": ""},
        ["run", "two_robot", "--events", "out.csv"],
        ["--events", "out.csv", "folder"],
    ),
    "negative seed": ({}, ["run", "two_robot", "--seed", "-3"], ["--seed"]),
    "unknown option": ({}, ["run", "two_robot", "--fast"], ["--fast"]),
    "trace file missing": (
        {"tr.toml": '[feeder]\narrival = "trace"\ntrace = "gone.csv"\n'},
        ["run", "tr.toml"],
        ["feeder.trace", "gone.csv"],
    ),
    "trace not given": (
        {"tr.toml": '[feeder]\narrival = "trace"\n'},
        ["run", "tr.toml"],
        ["feeder.trace", "required"],
    ),
    "trace non-numeric": (
        {
            "tr.yaml": "feeder: {arrival: trace, trace: t.csv}\n",
            "t.csv": "time,y\n0.1,0.2\nx,0.1\n",
        },
        ["run", "tr.yaml"],
        ["feeder.trace", "t.csv", "non-numeric"],
    ),
    "trace out of order": (
        {"tr.yaml": "feeder: {arrival: trace, trace: t.csv}\n", "t.csv": "time,y\n2,0.2\n1,0.1\n"},
        ["validate", "tr.yaml"],
        ["feeder.trace", "non-decreasing"],
    ),
    "trace off the belt": (
        {"tr.yaml": "feeder: {arrival: trace, trace: t.csv}\n", "t.csv": "time,y\n0.5,0.9\n"},
        ["run", "tr.yaml"],
        ["feeder.trace", "outside the belt"],
    ),
    "trace without header": (
        {"tr.yaml": "feeder: {arrival: trace, trace: t.csv}\n", "t.csv": "0.5,0.1\n0.7,0.2\n"},
        ["run", "tr.yaml"],
        ["feeder.trace", "header"],
    ),
}


@pytest.mark.parametrize("case", list(CASES))
def test_bad_input_gives_one_line_and_exit_2(
    case: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    files, args, needles = CASES[case]
    for name, text in files.items():
        (tmp_path / name).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / name).write_text(text)
    monkeypatch.chdir(tmp_path)
    result = CliRunner().invoke(app, args)
    assert result.exit_code == 2, result.output
    assert result.stdout == ""
    lines = result.stderr.splitlines()
    assert len(lines) == 1, result.stderr
    assert lines[0].startswith("error: ")
    assert "Traceback" not in result.stderr
    for needle in needles:
        assert needle in lines[0], f"{needle!r} not in {lines[0]!r}"


def test_no_output_file_is_left_by_a_failed_run(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.chdir(tmp_path)
    result = CliRunner().invoke(
        app, ["run", "two_robot", "--policy", "SD,SD,SD", "--events", "out/parts.csv"]
    )
    assert result.exit_code == 2
    assert not (tmp_path / "out" / "parts.csv").exists()
    assert not [p for p in tmp_path.rglob("*") if p.is_file()]
