"""Every kind of bad input ends with exit code 2 and one line naming the field and the value."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import pytest
from typer.testing import CliRunner

from pnp_twin.cli import app
from pnp_twin.twin.loader import (
    ScenarioError,
    apply_overrides,
    load_scenario,
    parse_value,
    validate,
    with_overrides,
)
from pnp_twin.twin.scenario import Scenario

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


# --- the loader and the model, directly -------------------------------------------------------

LAUGHS = 'a: &a ["lol","lol","lol","lol","lol","lol","lol","lol","lol"]\n' + "".join(
    f"{chr(98 + i)}: &{chr(98 + i)} [*{chr(97 + i)},*{chr(97 + i)},*{chr(97 + i)},*{chr(97 + i)}]\n"
    for i in range(9)
)


def scenario_error(tmp_path: Path, name: str, text: str | bytes) -> str:
    path = tmp_path / name
    path.write_bytes(text if isinstance(text, bytes) else text.encode("utf-8"))
    with pytest.raises(ScenarioError) as info:
        load_scenario(path)
    message = str(info.value)
    assert "\n" not in message and len(message) < 300, message
    return message


def test_billion_laughs_is_refused_without_expanding_or_echoing(tmp_path: Path) -> None:
    message = scenario_error(tmp_path, "laughs.yaml", LAUGHS)
    assert "aliases" in message and "line 2" in message and "lol" not in message


def test_non_utf8_and_huge_and_deep_files_are_one_line(tmp_path: Path) -> None:
    latin = 'name = "caf\xe9"\n'.encode("latin-1")
    assert "not UTF-8" in scenario_error(tmp_path, "latin.toml", latin)
    big = scenario_error(tmp_path, "big.yaml", "# " + "x" * 1_100_000 + "\n")
    assert "at most 1,000,000" in big
    assert "nested too deeply" in scenario_error(tmp_path, "deep.yaml", "[" * 5000 + "]" * 5000)


@pytest.mark.parametrize("text", ["", "# only a comment\n", "{}\n"])
def test_an_empty_scenario_file_is_refused(tmp_path: Path, text: str) -> None:
    assert "is empty" in scenario_error(tmp_path, "empty.yaml", text)


def test_a_long_bad_value_is_quoted_as_a_short_excerpt() -> None:
    with pytest.raises(ScenarioError) as info:
        validate({"robots": {"count": "x" * 5000}})
    message = str(info.value)
    assert len(message) < 200 and "more characters" in message


def test_override_values_are_numbers_when_they_read_as_numbers() -> None:
    assert parse_value("1e12") == 1e12 and parse_value("4") == 4
    assert math.isnan(parse_value("nan")) and parse_value("true") is True
    assert parse_value("[nan, 1e3]")[1] == 1000.0 and parse_value("SD") == "SD"
    assert parse_value("[[0, 1e3]]") == [[0, 1000.0]]


STRICT = [
    ("robots.count", True, "input should be a valid integer"),
    ("feeder.rate", "10", "input should be a valid number"),
    ("belt.speed", False, "input should be a valid number"),
    ("robots.bin_offset", [math.nan, math.inf], "finite number"),
    ("belt.length", math.inf, "finite number"),
    ("robots.pick_time", 1e300, "less than or equal to 60 s"),
    ("robots.arm_speed", 1e9, "less than or equal to 100 m/s"),
    ("feeder.rate", 1e12, "less than or equal to 1000 parts/s"),
    ("duration", 1e9, "less than or equal to 31536000 s"),
    ("bins.change_time", -1, "greater than or equal to 0 s"),
    ("seed", 2**64, "less than or equal to"),
    ("robots.count", 2.5, "valid integer"),
]


@pytest.mark.parametrize("path, value, needle", STRICT)
def test_strict_finite_bounded_numbers(path: str, value: object, needle: str) -> None:
    with pytest.raises(ScenarioError) as info:
        validate(apply_overrides({}, {path: value}))
    assert str(info.value).startswith(path) and needle in str(info.value), str(info.value)


def test_whole_floats_and_numpy_integers_are_whole_numbers() -> None:
    import numpy as np

    assert validate({"robots": {"count": 3.0}}).robots.count == 3
    assert validate({"robots": {"count": np.int64(2)}}).robots.count == 2


CONFLICTS: dict[str, tuple[dict[str, Any], str]] = {
    "trace with poisson": ({"feeder.trace": "t.csv"}, "feeder.trace: given, but"),
    "mean with uniform": (
        {"feeder.lateral": "uniform", "feeder.lateral_mean": 0.2},
        "feeder.lateral_mean: given, but",
    ),
    "spread wider than the belt": ({"feeder.lateral_sd": 5.0}, "wider than the belt"),
    "a crawling arm": ({"robots.acceleration": 1e-9}, "too low to reach belt speed"),
    "a crawling override": (
        {"robots.overrides": [{"robot": 2, "acceleration": 0.1}]},
        "robot 2 is too low",
    ),
    "internal field": ({"source_dir": "/etc"}, "source_dir: not a scenario field"),
    "duplicate policies": ({"sweep.policies": ["SD", "sd"]}, "'sd' is 'SD' again"),
    "duplicate mixes": ({"sweep.policies": ["SPT,FIFO", " spt, fifo "]}, "again"),
}


@pytest.mark.parametrize("case", list(CONFLICTS))
def test_conflicting_settings_are_refused(case: str) -> None:
    sets, needle = CONFLICTS[case]
    with pytest.raises(ScenarioError) as info:
        validate(apply_overrides({}, sets))
    assert needle in str(info.value), str(info.value)


def test_source_dir_is_set_by_the_loader_only() -> None:
    scenario = load_scenario("trace_replay")
    assert scenario.source_dir and "source_dir" not in scenario.model_dump()
    assert "source_dir" not in Scenario.model_json_schema()["properties"]
    assert with_overrides(scenario, {"warmup": 5.0}).source_dir == scenario.source_dir
    with pytest.raises(ScenarioError, match="source_dir: not a scenario field"):
        load_scenario("paper_baseline", {"source_dir": "/etc"})


def test_set_takes_text_fields_as_written() -> None:
    from pnp_twin.twin.loader import parse_sets

    sets = parse_sets(["name=on", "description=Line 3: week 12", "policy=SPT", "seed=007"])
    assert sets == {"name": "on", "description": "Line 3: week 12", "policy": "SPT", "seed": 7}
    scenario = load_scenario("two_robot", sets)
    assert scenario.name == "on" and scenario.description == "Line 3: week 12"
